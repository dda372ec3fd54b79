"""SemanticField: f(x) = (SDF(x), g([SH(dir) || x || z(x)])) over a cube around the object.

Points are metres in the object frame. They are normalised to x_n = (x - center) / bound
in [-1, 1]^3; points outside the cube are clamped onto its faces, so the SDF (and its
gradient, which is zero across the clamp) there is not meaningful: sample inside the bound.
The SDF MLP predicts distance in normalised units and the field returns it in metres
(times `bound`), so a unit-norm gradient in metres is the eikonal condition.

`bound` is not a setting: the map task computes it from the object (BOUND_MARGIN times
its bounding radius, tasks/build.py) and passes it beside the config.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch
from omegaconf import MISSING
from torch import Tensor, nn

from neuralfeels_sem.fields.hash_grid import HashGridConfig, HashGridEncoding
from neuralfeels_sem.fields.heads import MaterialHead, MaterialHeadConfig, SdfHead, SdfHeadConfig
from neuralfeels_sem.fields.material_support import MaterialSupport


@dataclass
class SemanticFieldConfig:
    """`model`: the semantic neural field (SDF + material branches); conf/model/*.yaml."""

    num_classes: int = MISSING  # conf/model: ${len:${materials}}
    # Centre (metres, object frame) of the field's cube; its half-extent is computed.
    center: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    encoding: HashGridConfig = field(default_factory=HashGridConfig)
    sdf: SdfHeadConfig = field(default_factory=SdfHeadConfig)
    material: MaterialHeadConfig = field(default_factory=MaterialHeadConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.num_classes, int) or self.num_classes < 2:
            raise ValueError(f"model.num_classes={self.num_classes} must be an integer >= 2")
        if len(self.center) != 3:
            raise ValueError(f"model.center={list(self.center)} must have 3 values")


def _check_points(x: Tensor) -> None:
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {tuple(x.shape)}")


class SemanticField(nn.Module):
    """Neural SDF with a parallel material-classification branch."""

    def __init__(self, config: SemanticFieldConfig, bound: float) -> None:
        """`bound`: half-extent (metres) of the cube [-bound, bound]^3 around the centre."""
        super().__init__()
        if bound <= 0:
            raise ValueError(f"bound={bound} must be > 0")
        self.num_classes = config.num_classes
        self.bound = float(bound)
        self.register_buffer("center", torch.tensor([float(c) for c in config.center]))
        self.encoding = HashGridEncoding(config.encoding)
        self.sdf_head = SdfHead(self.encoding.out_dim, config.sdf)
        material = config.material
        self.concat_sdf_features = material.concat_sdf_features
        self.backprop_to_sdf = material.backprop_to_sdf
        self.material_head = MaterialHead(
            config.num_classes,
            config.sdf.hidden_dim if material.concat_sdf_features else 0,
            material,
            sparse_grad=config.encoding.sparse_grad,
        )
        self.support: MaterialSupport | None = None  # set by the mapper (mapping.mapper.fill_m)

    def normalise(self, x: Tensor) -> Tensor:
        """Metres in the object frame -> [-1, 1]^3 (clamped)."""
        _check_points(x)
        return ((x - self.center) / self.bound).clamp(-1.0, 1.0)

    def _sdf_branch(self, x_n: Tensor) -> tuple[Tensor, Tensor]:
        features = self.encoding((x_n + 1.0) * 0.5)
        sdf_n, hidden = self.sdf_head(features)
        return sdf_n * self.bound, hidden

    def _material_branch(self, x_n: Tensor, hidden: Tensor | None) -> Tensor:
        if self.concat_sdf_features and not self.backprop_to_sdf and hidden is not None:
            hidden = hidden.detach()
        return self.material_head(x_n, hidden if self.concat_sdf_features else None)

    def forward(self, x: Tensor, material_from: int = 0) -> dict[str, Tensor]:
        """x (N, 3) metres -> {"sdf": (N,) metres, "material_logits": (N - material_from, C)
        of the rows from `material_from` on, "sdf_features": (N, H)}.

        A batch whose material loss uses only its last rows asks for those alone: the
        material branch on every row cost a mapper step about a tenth of its time."""
        if not 0 <= material_from <= len(x):
            raise ValueError(f"material_from={material_from} must be in [0, {len(x)}]")
        x_n = self.normalise(x)
        sdf, hidden = self._sdf_branch(x_n)
        logits = self._material_branch(x_n[material_from:], hidden[material_from:])
        return {"sdf": sdf, "material_logits": logits, "sdf_features": hidden}

    def sdf(self, x: Tensor) -> Tensor:
        """Signed distance (N,) in metres; skips the material branch."""
        return self._sdf_branch(self.normalise(x))[0]

    def material_logits(self, x: Tensor) -> Tensor:
        """Material class logits (N, C) as the map reads them: the material branch's, with
        the nearest trained touch's label mixed in beyond `support.fill_m` of every one when
        the mapper set a `support` (fields/material_support.py; training uses `forward`).
        Runs the SDF branch only when concatenating z(x)."""
        x_n = self.normalise(x)
        hidden = self._sdf_branch(x_n)[1] if self.concat_sdf_features else None
        logits = self._material_branch(x_n, hidden)
        if self.support is None:
            return logits
        probs = self.support.blend(x, torch.softmax(logits.float(), dim=-1))
        return torch.log(probs.clamp_min(1e-12))

    @torch.no_grad()
    def predict_material(self, x: Tensor) -> Tensor:
        """Most likely class index (N,) long."""
        return self.material_logits(x).argmax(dim=-1)

    def sdf_and_gradient(self, x: Tensor, create_graph: bool = True) -> tuple[Tensor, Tensor]:
        """(sdf (N,), d sdf / d x (N, 3)) by autograd from one forward pass.

        With `create_graph` (default) the gradient is differentiable, so a loss on it (the
        eikonal loss) trains the field; pass False for a cheaper read-only gradient (pose
        tracking, normals). Works under torch.no_grad.
        """
        _check_points(x)
        with torch.enable_grad():
            x = x.detach().requires_grad_(True)
            sdf = self.sdf(x)
            (grad,) = torch.autograd.grad(sdf.sum(), x, create_graph=create_graph)
        return sdf, grad

    def sdf_gradient(self, x: Tensor, create_graph: bool = True) -> Tensor:
        """d sdf / d x (N, 3) in metres per metre; see `sdf_and_gradient`."""
        return self.sdf_and_gradient(x, create_graph)[1]


def evaluate_chunked(
    fn: Callable[[Tensor], Tensor | dict[str, Tensor]],
    x: Tensor,
    chunk: int = 65536,
    no_grad: bool = True,
    progress: bool = False,
) -> Tensor | dict[str, Tensor]:
    """Apply `fn` to x (N, ...) in chunks of `chunk` rows and concatenate the results.

    `fn` returns a Tensor or a dict of Tensors (first dimension N). Used for dense queries
    (marching cubes over 128^3 to 256^3 points) that would not fit in memory at once.
    """
    if chunk < 1:
        raise ValueError(f"chunk={chunk} must be >= 1")
    if x.shape[0] == 0:
        raise ValueError("evaluate_chunked needs at least one point")
    starts = range(0, x.shape[0], chunk)
    if progress:
        from tqdm import tqdm

        starts = tqdm(starts, desc="field query", unit="chunk")
    outputs = []
    with torch.set_grad_enabled(not no_grad and torch.is_grad_enabled()):
        for start in starts:
            outputs.append(fn(x[start : start + chunk]))
    if isinstance(outputs[0], dict):
        return {key: torch.cat([o[key] for o in outputs]) for key in outputs[0]}
    return torch.cat(outputs)
