"""Prints the criterion medians of the engine benchmarks as a Markdown table.

Run after `cargo bench --bench substep` (and `--bench fmu_step`); reads
target/criterion/<group>/<bench>/new/estimates.json. Each benchmark advances
one 1 ms interval of 500 sub-steps, so the cost of a sub-step is the median
divided by 500.
"""

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUBSTEPS = 500


def main() -> int:
    base = ROOT / "target" / "criterion"
    rows = []
    for est in sorted(base.glob("*/*/new/estimates.json")):
        group, bench = est.parts[-4], est.parts[-3]
        median_ns = json.loads(est.read_text())["median"]["point_estimate"]
        rows.append((group, bench, median_ns))
    if not rows:
        print(f"no criterion results under {base}", file=sys.stderr)
        return 1
    print("| benchmark | median per 1 ms interval | per sub-step |")
    print("|---|---|---|")
    for group, bench, ns in rows:
        print(f"| {group}/{bench} | {ns / 1e3:.1f} µs | {ns / SUBSTEPS / 1e3:.3f} µs |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
