#!/usr/bin/env bash
# Write the pins of a tested environment: freeze_constraints.sh VENV OUT [WHAT]
# Every installed distribution as name==version (the project's own editable install left out),
# under a header that says what they are and how to renew them (`make upgrade-constraints`).
set -euo pipefail
venv=$1 out=$2 what=${3:-the project}
{
  echo "# Versions ${what} is tested with; \`make\` installs from these pins (pip -c)."
  echo "# Written by scripts/freeze_constraints.sh from a fresh environment: renew with"
  echo "# \`make upgrade-constraints\` (newest releases, then the whole test-suite), commit if green."
  echo "# Python $("$venv/bin/python" -c 'import platform; print(platform.python_version(), platform.machine())'), $(date -u +%Y-%m-%d)"
  "$venv/bin/python" -m pip freeze --exclude-editable --all | grep -v -i -E '^(pip|setuptools|wheel)==' | LC_ALL=C sort -f
} > "$out.tmp"
mv "$out.tmp" "$out"
echo "freeze_constraints: $(grep -c '==' "$out") pins in $out"
