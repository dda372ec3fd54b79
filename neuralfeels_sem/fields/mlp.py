"""Plain ReLU multilayer perceptron that also returns its last hidden features."""

from __future__ import annotations

from torch import Tensor, nn


class MLP(nn.Module):
    """in_dim -> num_layers x (Linear(hidden_dim) + ReLU) -> Linear(out_dim).

    `forward_with_hidden` also returns the last hidden activation: the SDF branch hands
    it to the material branch as z(x).
    """

    def __init__(self, in_dim: int, hidden_dim: int, num_layers: int, out_dim: int) -> None:
        super().__init__()
        if in_dim < 1 or hidden_dim < 1 or out_dim < 1 or num_layers < 1:
            raise ValueError(
                f"MLP needs in_dim={in_dim}, hidden_dim={hidden_dim}, out_dim={out_dim} "
                f"and num_layers={num_layers} all >= 1"
            )
        layers: list[nn.Module] = []
        dim = in_dim
        for _ in range(num_layers):
            layers += [nn.Linear(dim, hidden_dim), nn.ReLU()]
            dim = hidden_dim
        self.hidden = nn.Sequential(*layers)
        self.out = nn.Linear(hidden_dim, out_dim)
        self.in_dim = in_dim
        self.hidden_dim = hidden_dim
        self.out_dim = out_dim

    def forward_with_hidden(self, x: Tensor) -> tuple[Tensor, Tensor]:
        if x.ndim != 2 or x.shape[1] != self.in_dim:
            raise ValueError(f"MLP input must have shape (N, {self.in_dim}), got {tuple(x.shape)}")
        h = self.hidden(x)
        return self.out(h), h

    def forward(self, x: Tensor) -> Tensor:
        return self.forward_with_hidden(x)[0]
