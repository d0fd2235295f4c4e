"""Saving matplotlib figures the one way every plot in the project does.

Figures are built with matplotlib's object API (`new_figure`, a `matplotlib.figure.Figure` on
its own Agg canvas), so plotting neither imports pyplot nor switches the global backend: a
notebook's or GUI's backend stays as its user set it.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure


def new_figure(**kwargs: Any) -> Figure:
    """A figure outside pyplot's registry (no backend switch, nothing to close)."""
    return Figure(**kwargs)


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Lay out, write (creating the folder) and release; returns the path.

    Works without pyplot; a figure that was made through pyplot is also closed there.
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is not None:  # a no-op for figures pyplot does not manage
        pyplot.close(fig)
    return out
