"""The `threads` setting: auto follows OMP_NUM_THREADS, else one thread; N is N; bad values fail."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from threadpoolctl import threadpool_info, threadpool_limits

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.utils.device import resolve_threads, set_threads
from tests.helpers import compose_config


def test_auto_is_one_thread_without_omp_num_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert resolve_threads("auto") == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert resolve_threads("auto") == 3
    monkeypatch.setenv("OMP_NUM_THREADS", "lots")
    assert resolve_threads("auto") == 1


def _blas_threads() -> set[int]:
    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


def test_a_number_is_taken_as_is_and_set_once() -> None:
    before = torch.get_num_threads()
    try:
        assert resolve_threads(2) == resolve_threads("2") == 2
        assert set_threads("2") == 2 and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_numpy_blas_follows_the_thread_count() -> None:
    np.ones((4, 4)) @ np.ones((4, 4))  # numpy's BLAS is loaded
    before = torch.get_num_threads()
    with threadpool_limits(limits=2, user_api="blas"):  # restores this process's after
        assert _blas_threads() == {2}
        try:
            assert set_threads("1") == 1
            assert _blas_threads() == {1}
        finally:
            torch.set_num_threads(before)


@pytest.mark.parametrize("bad", ["0", "-1", "two", "1.5"])
def test_bad_values_fail_with_one_line(bad: str) -> None:
    with pytest.raises(ConfigError, match="threads="):
        resolve_threads(bad)
    cfg = compose_config([f"threads={bad}"])
    with pytest.raises(ConfigError) as info:
        validate_config(cfg)
    assert "threads" in str(info.value) and "\n" not in str(info.value)


def test_the_default_config_asks_for_auto() -> None:
    assert str(compose_config([]).threads) == "auto"
