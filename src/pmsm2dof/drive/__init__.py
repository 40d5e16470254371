"""The drive over XCP: the firmware's variables (ELF), its A2L file, the link (pyxcp) and the virtual drive.

The peer of :mod:`pmsm2dof.sim`: the simulation engine and the drive produce the same traces from
the same scenario. Imports only :mod:`pmsm2dof.core` and below; pyxcp and pyelftools are the
``drive`` extra.
"""
