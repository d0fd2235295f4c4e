"""The bench's policy section alone: default, default + probe, default (raw), paper,
classical, projection.

    nice -n 10 python benchmarks/policy_section.py [--seeds 20] [--out benchmarks/results]

Runs the 20-seed randomized suite, the paper's offsets and the resistance map with the dead
band derived from the sensor noise, and writes policy_section.json (the typed results) and
policy_section.md (the report's section, rendered from the JSON).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from constraint_aware.bench.analysis import PolicySection, policy_section
from constraint_aware.bench.report import policy_section_lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="suite seeds per task")
    parser.add_argument("--map-seeds", type=int, default=2, help="seeds per resistance cell")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args()
    start = time.perf_counter()
    section = policy_section(quick=False, suite_seeds=args.seeds, map_seeds=args.map_seeds)
    data = {
        "wall_time_s": time.perf_counter() - start,
        "load_average_1_5_15": os.getloadavg(),
        "section": section.to_dict(),
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "policy_section.json").write_text(json.dumps(data, indent=1) + "\n")
    again = PolicySection.from_dict(
        json.loads((out / "policy_section.json").read_text())["section"]
    )
    (out / "policy_section.md").write_text("\n".join(policy_section_lines(again)) + "\n")


if __name__ == "__main__":
    main()
