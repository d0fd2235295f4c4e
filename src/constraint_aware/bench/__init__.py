"""`cap bench`: the paper's experiments, the robustness maps, the embodiment, placement, policy
and fault sections, as results.json, figures and report.md.

`run_bench(out, quick=..., policy=..., robot=...)` runs it, `replot(out)` redraws from
results.json. Names are resolved on first use, so importing this package imports no simulator.
"""

from __future__ import annotations

from constraint_aware.lazy import lazy_getattr

_EXPORTS = {
    "load_results": "run",
    "policy_identity": "run",
    "replot": "run",
    "run_bench": "run",
    "BenchConfig": "experiments",
    "PolicySection": "analysis",
    "policy_section": "analysis",
    "EmbodimentResults": "embodiment",
    "embodiment_experiments": "embodiment",
    "FaultSuite": "faults",
    "fault_suite": "faults",
    "run_many": "sweep",
}
__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
