"""Writing figures, and long traces drawn at the resolution of the image.

A figure is saved as PNG or SVG in one atomic write (:func:`save_figure`). A line of more points
than the image has pixel columns is drawn from at most four points per column
(:func:`decimate`): the first, the smallest, the largest and the last of the column, in their
order. A line rasterised from them covers the same pixels as the line through every point, peaks
included (U. Jugel, Z. Jerzak, G. Hackenbroich, V. Markl, "M4: a visualization-oriented time
series data aggregation", Proc. VLDB Endowment 7(10), 2014), and a trace of 150 000 samples costs
the drawing of a few thousand. This module imports matplotlib only for types, so that a command
pays for it only when it draws.
"""

import io
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ...errors import ConfigError
from ...outputs import atomic_write

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: File formats :func:`save_figure` writes, by extension.
FORMATS = {".png": "png", ".svg": "svg"}

#: Resolution of saved figures [dots per inch].
DPI = 120


def decimate(
    x: npt.NDArray[np.float64], y: npt.NDArray[np.float64], x_lo: float, x_hi: float, columns: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The points of the line ``(x, y)`` that matter in ``columns`` pixel columns over ``[x_lo, x_hi]``.

    Per column (``x`` increasing): its first, smallest, largest and last point, in the order of
    ``x`` (M4, see the module docstring). A line of at most ``4 columns`` points is returned whole.
    """
    n = len(x)
    if n <= 4 * columns or not x_hi > x_lo:
        return x, y
    column = np.clip(((x - x_lo) * (columns / (x_hi - x_lo))).astype(np.int64), 0, columns - 1)
    first = np.flatnonzero(np.concatenate(([True], column[1:] != column[:-1])))
    last = np.concatenate((first[1:], [n])) - 1
    # sorted by column, then by y: each column's run begins with its smallest and ends with its largest
    order = np.lexsort((y, column))
    keep = np.unique(np.concatenate((first, last, order[first], order[last])))
    return x[keep], y[keep]


def decimate_lines(fig: "Figure", dpi: int = DPI) -> None:
    """Replace the data of every long line of ``fig`` by :func:`decimate`.

    The columns are those of the whole figure's width at ``dpi``, at least as many as any axes has
    (constrained layout places the axes only when the figure is drawn); the range is the axes' x limits.
    """
    columns = max(1, int(np.ceil(fig.get_figwidth() * dpi)))
    for ax in fig.axes:
        x_lo, x_hi = ax.get_xlim()
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata(), dtype=float)
            if len(x) > 4 * columns and np.all(np.diff(x) >= 0):
                line.set_data(*decimate(x, np.asarray(line.get_ydata(), dtype=float), x_lo, x_hi, columns))


def save_figure(fig: "Figure", path: Path | str) -> Path:
    """Save ``fig`` to ``path`` (``.png`` or ``.svg``) in one atomic write; return the path."""
    path = Path(path)
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise ConfigError("out", str(path), "a file name ending in " + " or ".join(FORMATS))
    buffer = io.BytesIO()
    fig.savefig(buffer, format=fmt, dpi=DPI)
    atomic_write(path, buffer.getvalue())
    return path
