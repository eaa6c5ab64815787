#!/usr/bin/env bash
# Install whatever is missing, then run a task:
#   bash setup.sh run   - the built-in default scene: SPICE, ODE and exact solutions compared
#   bash setup.sh test  - the test suite
# Missing pieces: the ngspice shared library and executable (Debian libngspice0, ngspice),
# Python's venv module, and a virtual environment .venv with analogy and its dependencies;
# for the tests also Chromium (Debian chromium) and a font, for the browser check of the report.
set -euo pipefail
cd "$(dirname "$0")"
task="${1:-run}"
shift || true
case "$task" in run|test) ;; *) echo "usage: bash setup.sh run|test" >&2; exit 2 ;; esac

PYTHON="${PYTHON:-python3}"
packages=()
"$PYTHON" -c 'import ctypes.util, sys; sys.exit(0 if ctypes.util.find_library("ngspice") else 1)' \
    || packages+=(libngspice0)
command -v ngspice >/dev/null 2>&1 || packages+=(ngspice)
"$PYTHON" -c 'import venv, ensurepip' >/dev/null 2>&1 || packages+=(python3-venv)
# the test suite opens the HTML report in a real browser
if [ "$task" = test ]; then
    command -v chromium >/dev/null 2>&1 || packages+=(chromium)
    [ -d /usr/share/fonts/truetype/dejavu ] || packages+=(fonts-dejavu-core)
fi

if [ "${#packages[@]}" -gt 0 ]; then
    echo "setup: installing Debian packages: ${packages[*]}"
    if [ "$(id -u)" -eq 0 ]; then sudo=(); elif command -v sudo >/dev/null; then sudo=(sudo); else
        echo "setup: need root (or sudo) to install ${packages[*]}" >&2; exit 1; fi
    "${sudo[@]}" apt-get update -qq
    DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends \
        "${packages[@]}" >/dev/null
fi

extras=""
[ "$task" = test ] && extras="[test]"
stamp=".venv/.installed$(echo "$extras" | tr -d '[]')"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv"
    "$PYTHON" -m venv .venv
fi
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "setup: installing analogy${extras} into .venv"
    .venv/bin/python -m pip install -q --disable-pip-version-check -e ".${extras}"
    echo "$want" > "$stamp"
fi

if [ "$task" = run ]; then
    mkdir -p out
    exec .venv/bin/analogy compare --csv out/default.csv --plot out/default.png "$@"
else
    exec .venv/bin/python -m pytest -q "$@"
fi
