"""Benchmarks: each `bench_<name>.py` module here exposes `run() -> dict` of measured figures.

`make bench` (python -m neuralfeels_sem.bench) runs them all and writes bench.json.
Speed and memory targets live here, never in timed tests. The other modules are
command-line diagnostics of the default rig (finger_contacts, rig_touches): like the
benchmarks they sit at the top of the layer order and may import any package.
"""
