"""A sphinx-gallery image scraper for the package's own figures.

The plotting functions of :mod:`pmsm2dof.ui.plots` return ``matplotlib.figure.Figure`` objects on
the Agg canvas, outside pyplot, so sphinx-gallery's matplotlib scraper does not see them. This
scraper shows each such figure that a code block of an example left in a variable, once, in the
order the block made them.
"""

from matplotlib.figure import Figure
from sphinx_gallery.scrapers import figure_rst

_shown = {}  # example file -> ids of the figures already shown


def scrape(block, block_vars, gallery_conf, **kwargs):
    """Save the new Figure objects of the example's namespace and return their reST."""
    shown = _shown.setdefault(block_vars["src_file"], set())
    figures = [value for value in block_vars["example_globals"].values() if isinstance(value, Figure)]
    paths = []
    for fig, path in zip((f for f in figures if id(f) not in shown), block_vars["image_path_iterator"]):
        fig.savefig(path, dpi=100)
        shown.add(id(fig))
        paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])
