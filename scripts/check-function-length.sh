#!/usr/bin/env bash
# The project's rule "no function over 80 lines", measured: every function definition in the C++
# files under the given folders, from the line of its name to its closing brace (Universal Ctags'
# `line` and `end`; lambdas count towards the function they are in).
#
#   scripts/check-function-length.sh [--limit N] [--informational DIR]... DIR...
#
# Prints each function over the limit as "LINES FILE:LINE NAME" and exits 1 if one lies in a
# DIR; those in an --informational DIR are printed but do not fail (a folder whose owner has its
# split still to land). Exit 2 on a usage error or without Universal Ctags (Debian:
# universal-ctags, scripts/install-deps.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
limit=80
checked=()
informational=()
while [ $# -gt 0 ]; do
  case "$1" in
    --limit) limit=$2; shift 2 ;;
    --informational) informational+=("$2"); shift 2 ;;
    -*) echo "usage: $0 [--limit N] [--informational DIR]... DIR..." >&2; exit 2 ;;
    *) checked+=("$1"); shift ;;
  esac
done
if [ ${#checked[@]} -eq 0 ] && [ ${#informational[@]} -eq 0 ]; then
  echo "usage: $0 [--limit N] [--informational DIR]... DIR..." >&2
  exit 2
fi
if ! ctags --version 2>/dev/null | grep -q "Universal Ctags"; then
  echo "check-function-length: needs Universal Ctags (apt-get install universal-ctags)" >&2
  exit 2
fi

# "LINES FILE:LINE NAME" for every function over the limit in the folders given.
long_functions() {
  find "$@" -type f \( -name '*.cc' -o -name '*.h' \) -print0 | sort -z |
    xargs -0 -r ctags -x --language-force=C++ --kinds-C++=f --fields=+ne \
      --_xformat='%n %e %F %N' -o - 2>/dev/null |
    awk -v limit="$limit" '$2 != "" && $2 - $1 + 1 > limit { print $2 - $1 + 1, $3 ":" $1, $4 }' |
    sort -rn
}

status=0
if [ ${#checked[@]} -gt 0 ]; then
  found=$(long_functions "${checked[@]}")
  if [ -n "$found" ]; then
    echo "Functions over $limit lines:"
    echo "$found"
    status=1
  else
    echo "No function over $limit lines in ${checked[*]}."
  fi
fi
if [ ${#informational[@]} -gt 0 ]; then
  found=$(long_functions "${informational[@]}")
  if [ -n "$found" ]; then
    echo "Functions over $limit lines (informational, not failing: ${informational[*]}):"
    echo "$found"
  fi
fi
exit $status
