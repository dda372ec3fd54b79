"""Camera keyframes: what the mapper remembers of the camera (touches: touch_memory.py).

Camera frames are many and redundant, so training uses a window: the most recent
keyframes plus older ones drawn with probability proportional to their last loss (the
frames the field explains worst, as in iSDF).

All points are stored in the object frame, as float32 tensors on the mapper's device.
"""

from __future__ import annotations

import torch


def check_points(points: torch.Tensor, name: str) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {tuple(points.shape)}")


class KeyframeBuffer:
    """Camera keyframes: object-frame surface points and the camera centre of each."""

    def __init__(self, max_keyframes: int, window_recent: int, window_by_loss: int) -> None:
        if max_keyframes < 1 or window_recent < 1 or window_by_loss < 0:
            raise ValueError(
                f"need max_keyframes >= 1, window_recent >= 1, window_by_loss >= 0; got "
                f"{max_keyframes}, {window_recent}, {window_by_loss}"
            )
        self.max_keyframes = max_keyframes
        self.window_recent = window_recent
        self.window_by_loss = window_by_loss
        self.points: list[torch.Tensor] = []
        self.origins: list[torch.Tensor] = []  # (3,) camera centre per keyframe
        self.frame_indices: list[int] = []
        self.losses: list[float] = []

    def __len__(self) -> int:
        return len(self.points)

    def add(self, points: torch.Tensor, origin: torch.Tensor, frame_index: int) -> None:
        check_points(points, "keyframe points")
        if origin.shape != (3,):
            raise ValueError(f"keyframe origin must have shape (3,), got {tuple(origin.shape)}")
        if points.shape[0] == 0:
            return
        # New keyframes start with the highest known loss so they are drawn soon.
        self.points.append(points)
        self.origins.append(origin)
        self.frame_indices.append(int(frame_index))
        self.losses.append(max(self.losses, default=1.0))
        if len(self.points) > self.max_keyframes:
            self._evict()

    def _evict(self) -> None:
        """Drop the best-explained keyframe outside the recent window."""
        old = range(len(self.points) - self.window_recent)
        drop = min(old, key=lambda i: self.losses[i])
        for store in (self.points, self.origins, self.frame_indices, self.losses):
            del store[drop]

    def window(self, generator: torch.Generator) -> list[int]:
        """Indices of the keyframes to train on: recent ones plus older ones drawn by loss."""
        n = len(self.points)
        recent = list(range(max(0, n - self.window_recent), n))
        n_old = n - len(recent)
        if n_old == 0 or self.window_by_loss == 0:
            return recent
        weights = torch.tensor(self.losses[:n_old], dtype=torch.float64).clamp_min(1e-12)
        k = min(self.window_by_loss, n_old)
        chosen = torch.multinomial(weights, k, replacement=False, generator=generator)
        return sorted(int(i) for i in chosen) + recent

    def move_frame(self, frame_index: int, rotation: torch.Tensor, shift: torch.Tensor) -> int:
        """Re-place the keyframes of one frame (x -> rotation x + shift, object frame: its
        pose was refined); how many were moved."""
        moved = 0
        for i, index in enumerate(self.frame_indices):
            if index == frame_index:
                self.points[i] = self.points[i] @ rotation.T + shift
                self.origins[i] = rotation @ self.origins[i] + shift
                moved += 1
        return moved

    def update_losses(self, keyframe_ids: list[int], losses: list[float]) -> None:
        for i, loss in zip(keyframe_ids, losses):
            self.losses[i] = float(loss)

    def state_dict(self) -> dict:
        return {
            "points": list(self.points),
            "origins": list(self.origins),
            "frame_indices": list(self.frame_indices),
            "losses": list(self.losses),
        }

    def load_state_dict(self, state: dict, device: torch.device) -> None:
        self.points = [p.to(device) for p in state["points"]]
        self.origins = [o.to(device) for o in state["origins"]]
        self.frame_indices = [int(i) for i in state["frame_indices"]]
        self.losses = [float(v) for v in state["losses"]]
