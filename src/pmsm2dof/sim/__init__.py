"""Simulation: scenarios, the compiled drive engine, the figures of merit of a run.

:mod:`.scenario` reads and validates scenarios (TOML, the shipped presets), :mod:`.simulate` runs
one in the compiled engine and returns its :class:`~pmsm2dof.sim.simulate.Result`,
:mod:`.metrics` measures it. Imports :mod:`pmsm2dof.core` only.
"""
