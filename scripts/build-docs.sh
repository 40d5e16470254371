#!/usr/bin/env bash
# Build the documentation site into site/ (open site/index.html): the pages of docs/ and the
# repository's Markdown, the Python API from the docstrings, the C API from the headers, and the
# gallery, whose examples (examples/plot_*.py) run during the build. Warnings are errors: a broken
# link, a docstring Sphinx cannot read or an example that raises fails the build.
# Needs the docs extra: python3 -m pip install -e ".[docs]" (scripts/install.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
export MPLBACKEND=Agg
# The source folder is the repository root (docs/conf.py says which files are pages), so the site's
# start page is site/docs/index.html; site/index.html leads there. Every build reads every page again
# (-E: a header or a figure script is not a dependency Sphinx tracks), runs every example of the gallery
# and draws every figure (the plot directive redraws only for a changed script, so its cache goes): an
# unchanged example or figure can still break on a change of the package.
rm -rf .docs-cache/plot_directive
python3 -m sphinx -b html -E -W --keep-going -q -c docs -d .docs-cache/doctrees . site "$@"
cat > site/index.html <<'HTML'
<!DOCTYPE html>
<meta charset="utf-8">
<title>pmsm2dof</title>
<meta http-equiv="refresh" content="0; url=docs/index.html">
<a href="docs/index.html">pmsm2dof documentation</a>
HTML
echo "built site/index.html"
