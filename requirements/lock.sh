#!/usr/bin/env bash
# Regenerates requirements/lock.txt: every dependency of the project and of all its extras,
# resolved by pip-tools to exact versions for CPython 3.11 on Linux x86_64 (the CI machine).
# The ranges stay in pyproject.toml for library users; the README's commands and .ci/run
# install with `-c requirements/lock.txt`.
#
#   requirements/lock.sh             keep the current pins where they still resolve
#   requirements/lock.sh --upgrade   resolve the newest releases the ranges admit
#   LOCK_OUT=FILE requirements/lock.sh --upgrade   write elsewhere (.ci/run's drift check)
#
# torch is written without its local label (+cpu): the pin then admits the CPU build that the
# README installs first, from this machine's wheel directory or PyTorch's CPU index.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${LOCK_OUT:-requirements/lock.txt}"
tools="$(mktemp -d)"
trap 'rm -rf "$tools"' EXIT
python3 -m venv "$tools/venv"
"$tools/venv/bin/pip" install -q "pip-tools==7.6.2"
# pip-compile reuses the pins of an existing output file unless --upgrade is given
if [ "$out" != requirements/lock.txt ] && [ -f requirements/lock.txt ]; then
  cp requirements/lock.txt "$out"
fi
CUSTOM_COMPILE_COMMAND="requirements/lock.sh" "$tools/venv/bin/pip-compile" -q --all-extras \
  --strip-extras --no-emit-index-url --no-emit-find-links --no-emit-trusted-host \
  --output-file "$out" "$@" pyproject.toml
sed -i -E 's/^torch==([0-9][0-9.]*)\+[a-z0-9]+/torch==\1/' "$out"
