"""The figure of an identification: the torque balance of each regression row, fit and residual."""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...studies.identify import Mechanics
from .design import save_figure


def plot_fit(mech: Mechanics, path: Path) -> None:
    """Draw the rows of :func:`~pmsm2dof.studies.identify.identify_mechanics` against time to ``path``.

    Top: the mean torque of each row (``y``, the torque integral over the row) and the model's
    ``J x_J + B x_B + Tc x_C``; rows excluded as outliers marked. Bottom: the residual [Nm].
    """
    fig = Figure(figsize=(9, 6), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True)
    rows = mech.rows
    t, y, fit, kept = rows["t_s"], rows["y"], rows["fit"], rows["kept"]
    top.plot(t, y, ".", ms=3, label="mean torque of the row (log)")
    top.plot(t, fit, "-", lw=1, label="J dw/dt + B w + Tc sign(w) (fit)")
    top.plot(t[~kept], y[~kept], "x", color="tab:red", label="excluded (outlier)")
    top.set_ylabel("torque [Nm]")
    top.set_title(
        f"J = {mech.J_kgm2:.5g} kg m^2, B = {mech.B_Nms:.4g} Nm s/rad, Tc = {mech.T_coulomb_Nm:.4g} Nm "
        f"({mech.n_rows} rows of {mech.window_s:.3g} s)"
    )
    top.legend(loc="best", fontsize="small")
    bottom.plot(t[kept], (y - fit)[kept], ".", ms=3)
    bottom.plot(t[~kept], (y - fit)[~kept], "x", color="tab:red")
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_ylabel("residual [Nm]")
    bottom.set_xlabel("time [s]")
    lim = 4 * float(np.std((y - fit)[kept])) or 1.0
    bottom.set_ylim(-lim, lim)
    save_figure(fig, path)
