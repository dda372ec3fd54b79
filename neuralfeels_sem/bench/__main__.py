"""Run every benchmark module and write one JSON report."""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import pkgutil
import sys
import time
import traceback

import neuralfeels_sem  # noqa: F401  (headless rendering defaults)
import neuralfeels_sem.bench as bench_pkg
from neuralfeels_sem.tasks.info import collect_info


def discover(only: list[str] | None) -> list[str]:
    names = sorted(
        m.name for m in pkgutil.iter_modules(bench_pkg.__path__) if m.name.startswith("bench_")
    )
    if only:
        names = [n for n in names if any(o in n for o in only)]
    return names


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="SemanticFeels benchmarks")
    parser.add_argument("--out", default="bench.json", help="report path")
    parser.add_argument("--only", nargs="*", help="substrings of benchmark names to run")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    report = {
        "machine": collect_info(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "results": {},
    }
    failed = 0
    for name in discover(args.only):
        print(f"[bench] {name} ...", flush=True)
        start = time.perf_counter()
        try:
            result = importlib.import_module(f"neuralfeels_sem.bench.{name}").run()
        except Exception as exc:  # one broken benchmark must not hide the others' figures
            failed += 1
            traceback.print_exc()
            result = {"error": f"{type(exc).__name__}: {exc}"}
        result["bench_wall_s"] = round(time.perf_counter() - start, 2)
        # Shared machines: a figure means little without the load it was measured at.
        result.setdefault("load_average_1min", round(os.getloadavg()[0], 2))
        report["results"][name.removeprefix("bench_")] = result
        print(f"[bench] {name}: {json.dumps(result)}", flush=True)
    with open(args.out, "w") as f:
        json.dump(report, f, indent=2)
    print(f"[bench] wrote {args.out}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
