"""Figures: design Bode and step plots (:mod:`~pmsm2dof.ui.plots.design`), the trace of a run
(:mod:`~pmsm2dof.ui.plots.trace`), the figures of a sweep (:mod:`~pmsm2dof.ui.plots.sweep`), the
Pareto front of an autotuning (:mod:`~pmsm2dof.ui.plots.autotune`) and the firmware's run over the
engine's (:mod:`~pmsm2dof.ui.plots.firmware`), on matplotlib's Agg canvas."""
