"""Figures: design Bode and step plots (:mod:`.design`), the trace of a run (:mod:`.trace`) and
the figures of a sweep (:mod:`.sweep`), on matplotlib's Agg canvas."""
