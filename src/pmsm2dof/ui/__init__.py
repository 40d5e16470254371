"""The user interface: the ``pmsm2dof`` command, plots, the reproduction report and the tuner.

The only layer that knows about command-line flags, files of figures and web pages; it imports
the layers below (:mod:`pmsm2dof.studies`, :mod:`pmsm2dof.sim`, :mod:`pmsm2dof.analysis`,
:mod:`pmsm2dof.core`), which never import it.

The command groups that live in modules of their own (:mod:`pmsm2dof.ui.cli_drive`) import the
shared options of :mod:`pmsm2dof.ui.cli` and are registered here, so that no two sibling modules
import each other.
"""

from .cli import cli
from .cli_drive import drive

cli.add_command(drive)
