"""One module per task; each exposes `run(cfg) -> dict` and is named by conf/task/<name>.yaml.

Besides the tasks: runner.py (validate, seed, run one task) and callbacks.py (Hydra
callbacks, e.g. the end-of-sweep aggregate).
"""
