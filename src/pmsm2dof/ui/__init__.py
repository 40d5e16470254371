"""The user interface: the ``pmsm2dof`` command, plots, the reproduction report and the tuner.

The only layer that knows about command-line flags, files of figures and web pages; it imports
the layers below (:mod:`pmsm2dof.studies`, :mod:`pmsm2dof.sim`, :mod:`pmsm2dof.analysis`,
:mod:`pmsm2dof.core`), which never import it.
"""
