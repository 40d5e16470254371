#!/usr/bin/env bash
# The C sources of the project (csrc/, examples/; generated files are never tracked) against
# .clang-format. Default: check, print every violation and exit 1 if there is one;
# --fix: rewrite the files. Needs clang-format 14 (scripts/install.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v clang-format >/dev/null; then
  echo "clang-format is not installed: run scripts/install.sh (Debian package clang-format)" >&2
  exit 2
fi
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -d '' files < <(git ls-files -z 'csrc/*.[ch]' 'examples/*.[ch]')
else
  mapfile -d '' files < <(find csrc examples -name '*.[ch]' -print0 | sort -z)
fi
if [ "${1:-}" = "--fix" ]; then
  clang-format -i "${files[@]}"
else
  clang-format --dry-run -Werror "${files[@]}"
fi
