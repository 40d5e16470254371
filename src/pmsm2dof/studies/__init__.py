"""Studies: many simulations of scenarios, and what they measure together.

:mod:`.engine` is the one engine that runs many simulations (threads without the GIL or a Dask
cluster, batches, progress, resumable parts); :mod:`.sweep` runs the sweep files of
``pmsm2dof sweep`` on it, :mod:`.paper` the studies of the paper reproduction and
:mod:`.faults` the fault scenarios, :mod:`.autotune` the search for the best design,
:mod:`.configuration` the one scenario -> C configuration of the firmware (every header), and
:mod:`.firmware` the firmware built for a scenario and run closed loop on the emulated MCU.
Imports :mod:`pmsm2dof.sim`, :mod:`pmsm2dof.analysis` and
:mod:`pmsm2dof.core`, never the user interface.
"""
