"""One module per task; each exposes `run(cfg) -> dict` and is named by conf/task/<name>.yaml."""
