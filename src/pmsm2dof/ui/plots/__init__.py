"""Figures: design Bode and step plots (:mod:`~pmsm2dof.ui.plots.design`), the trace of a run
(:mod:`~pmsm2dof.ui.plots.trace`), the figures of a sweep (:mod:`~pmsm2dof.ui.plots.sweep`) and the
Pareto front of an autotuning (:mod:`~pmsm2dof.ui.plots.autotune`), on matplotlib's Agg canvas."""
