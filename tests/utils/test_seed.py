"""seed_everything: same draws for the same seed, deterministic algorithms on, bad seeds refused."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import torch

from neuralfeels_sem.utils.seed import seed_everything


def test_the_same_seed_gives_the_same_draws() -> None:
    seed_everything(3)
    first = (np.random.rand(3), torch.rand(3))
    seed_everything(3)
    again = (np.random.rand(3), torch.rand(3))
    assert np.array_equal(first[0], again[0]) and torch.equal(first[1], again[1])


def test_deterministic_algorithms_are_on_in_warn_only_mode() -> None:
    seed_everything(0)
    assert torch.are_deterministic_algorithms_enabled()
    assert torch.is_deterministic_algorithms_warn_only_enabled()


def test_seeding_does_not_load_the_compiler() -> None:
    # The public torch call imports torch._inductor / torch._dynamo (over a second).
    code = (
        "import sys; from neuralfeels_sem.utils.seed import seed_everything; seed_everything(1); "
        "print('torch._inductor' in sys.modules, 'torch._dynamo' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_a_loaded_compiler_gets_the_flag_too() -> None:
    import torch._inductor.config as inductor_config

    inductor_config.deterministic = False
    seed_everything(0)
    assert inductor_config.deterministic is True


def test_negative_seed_is_refused() -> None:
    with pytest.raises(ValueError, match="seed must be >= 0"):
        seed_everything(-1)
