"""Figures: design Bode and step plots (:mod:`.design`), the trace of a run (:mod:`.trace`), the
figures of a sweep (:mod:`.sweep`) and the Pareto front of an autotuning (:mod:`.autotune`), on
matplotlib's Agg canvas."""
