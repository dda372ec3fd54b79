"""Benchmarks: each `bench_<name>.py` module here exposes `run() -> dict` of measured figures.

`make bench` (python -m neuralfeels_sem.bench) runs them all and writes bench.json.
Speed and memory targets live here, never in timed tests.
"""
