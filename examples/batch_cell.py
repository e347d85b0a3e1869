# /// script
# requires-python = ">=3.10"
# dependencies = ["singplan"]
# ///
"""Plan every example task of this folder as one batch and print the summary table.

    python examples/batch_cell.py [OUT] [--workers N]

The same as `singplan batch examples/*.yaml -o OUT`: one folder per task in OUT, plus
OUT/summary.csv and OUT/summary.json. The top level is guarded by ``if __name__ ==
"__main__"``: the worker processes import this script.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from singplan.batch import plan_many


def main() -> int:
    parser = argparse.ArgumentParser(description="plan the example tasks as one batch")
    parser.add_argument("out", nargs="?", default="batch-out", help="batch folder (default: batch-out)")
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: CPUs)")
    args = parser.parse_args()
    tasks = sorted(Path(__file__).parent.glob("*.yaml"))
    result = plan_many(tasks, args.out, workers=args.workers, report=False, replay=False,
                       progress=lambda r, done, total: print(f"[{done}/{total}] {r.folder}: exit {r.exit_code}"))
    print(f"{'task':28s} exit  duration [s]  crossings  max dev [mm / deg]")
    for r in result.records:
        if r.exit_code == 0:
            print(f"{r.folder:28s} {r.exit_code:4d}  {r.duration_s:12.3f}  {r.crossings:9d}  "
                  f"{r.max_position_error_mm:.4f} / {r.max_orientation_error_deg:.4f}")
        else:
            print(f"{r.folder:28s} {r.exit_code:4d}  {r.message}")
    print(f"summary: {result.summary_csv}")
    return result.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
