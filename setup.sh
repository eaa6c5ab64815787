#!/usr/bin/env bash
# Install whatever is missing, then run a task:
#   bash setup.sh run   - the built-in default scene: SPICE, ODE and exact solutions compared
#   bash setup.sh test  - the test suite
#   bash setup.sh engine - the SPICE tests again, against ngspice 46 (Debian bookworm-backports)
# Missing pieces: the ngspice shared library and executable (Debian libngspice0, ngspice),
# Python's venv module, and a virtual environment .venv with analogy and its dependencies;
# for the tests also Chromium (Debian chromium) and a font, for the browser check of the report,
# gnucap, and where npm exists ngspice compiled to WebAssembly (npm eecircuit-engine, in .engines/wasm);
# for the deep pass (test -m deep) KiCad 9 from bookworm-backports, whose kicad-cli reads our schematics.
set -euo pipefail
cd "$(dirname "$0")"
task="${1:-run}"
shift || true
case "$task" in run|test|engine) ;; *) echo "usage: bash setup.sh run|test|engine" >&2; exit 2 ;; esac

PYTHON="${PYTHON:-python3}"
packages=()
"$PYTHON" -c 'import ctypes.util, sys; sys.exit(0 if ctypes.util.find_library("ngspice") else 1)' \
    || packages+=(libngspice0)
command -v ngspice >/dev/null 2>&1 || packages+=(ngspice)
"$PYTHON" -c 'import venv, ensurepip' >/dev/null 2>&1 || packages+=(python3-venv)
# the test suite opens the HTML report in a real browser
if [ "$task" != run ]; then
    command -v chromium >/dev/null 2>&1 || packages+=(chromium)
    [ -d /usr/share/fonts/truetype/dejavu ] || packages+=(fonts-dejavu-core)
    command -v gnucap >/dev/null 2>&1 || packages+=(gnucap)
    # without its default plugins gnucap reads no netlist (they are only a Recommends)
    ls /usr/lib/*/gnucap*/gnucap-default-plugins.so >/dev/null 2>&1 || packages+=(gnucap-default-plugins0)
fi

if [ "$(id -u)" -eq 0 ]; then sudo=(); elif command -v sudo >/dev/null; then sudo=(sudo); else sudo=(false); fi
if [ "${#packages[@]}" -gt 0 ]; then
    echo "setup: installing Debian packages: ${packages[*]}"
    [ "${sudo[*]}" = false ] && { echo "setup: need root (or sudo) to install ${packages[*]}" >&2; exit 1; }
    "${sudo[@]}" apt-get update -qq
    DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends \
        "${packages[@]}" >/dev/null
fi

# bookworm-backports from the archive the machine's own apt configuration names for bookworm, as a
# sources file at $1 (never a hard-coded address)
backports_sources() {
    grep -q '^12' /etc/debian_version 2>/dev/null || { echo "setup: bookworm-backports is for Debian 12 only" >&2; return 1; }
    local site
    site="$(apt-get indextargets --format '$(SITE) $(RELEASE)' 2>/dev/null | awk '$2 == "bookworm" {print $1; exit}')"
    [ -n "$site" ] || { echo "setup: the apt configuration names no bookworm archive" >&2; return 1; }
    printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
        "$site" > "$1"
}

# KiCad 9 for the deep pass's schematic check (kicad-cli; Debian 12's own KiCad 6 has none): installed
# from bookworm-backports by one apt call that reads the system's sources plus backports
kicad9() {
    command -v kicad-cli >/dev/null 2>&1 && return 0
    [ "${sudo[*]}" != false ] || return 1
    local parts=.engines/apt-kicad
    rm -rf "$parts" && mkdir -p "$parts"
    cp /etc/apt/sources.list.d/*.sources /etc/apt/sources.list.d/*.list "$parts"/ 2>/dev/null || true
    backports_sources "$parts/backports.sources" || return 1
    local apt=(apt-get -qq -o Dir::Etc::sourceparts="$PWD/$parts")
    echo "setup: installing KiCad 9 (kicad-cli) from bookworm-backports for the schematic check"
    "${sudo[@]}" "${apt[@]}" update && DEBIAN_FRONTEND=noninteractive "${sudo[@]}" "${apt[@]}" install -y \
        --no-install-recommends kicad/bookworm-backports >/dev/null
}

# ngspice 46 beside the system's: unpacked from bookworm-backports into .engines/ngspice-46, with
# its own lists (the system's apt sources are left alone) and its code-model paths pointed there
ngspice46() {
    local root=.engines/ngspice-46 lists=.engines/apt
    [ -x "$root/bin/ngspice" ] && [ -n "$(ls "$root"/usr/lib/*/libngspice.so.0 2>/dev/null)" ] && return 0
    grep -q '^12' /etc/debian_version 2>/dev/null || { echo "setup: ngspice 46 is fetched on Debian 12 only" >&2; return 1; }
    rm -rf "$root" "$lists"
    mkdir -p "$lists/lists/partial" "$lists/cache/archives/partial"
    backports_sources "$lists/backports.sources" || return 1
    local apt=(apt-get -qq -o Dir::Etc::sourcelist="$PWD/$lists/backports.sources" -o Dir::Etc::sourceparts=-
               -o Dir::State::Lists="$PWD/$lists/lists" -o Dir::Cache="$PWD/$lists/cache")
    "${apt[@]}" update || return 1
    (cd "$lists" && "${apt[@]}" download libngspice0/bookworm-backports ngspice/bookworm-backports 2>/dev/null) || return 1
    local debs=("$lists"/*ngspice*_46*.deb)
    [ -f "${debs[0]}" ] || { echo "setup: bookworm-backports has no ngspice 46" >&2; return 1; }
    for deb in "${debs[@]}"; do dpkg -x "$deb" "$root" || return 1; done
    local here="$PWD/$root" spinit="$root/usr/share/ngspice/scripts/spinit"
    [ -f "$spinit" ] && [ -n "$(ls "$root"/usr/lib/*/libngspice.so.0 2>/dev/null)" ] || return 1
    sed -i "s#/usr/lib/x86_64-linux-gnu/ngspice#$here/usr/lib/x86_64-linux-gnu/ngspice#g; s#/usr/lib/aarch64-linux-gnu/ngspice#$here/usr/lib/aarch64-linux-gnu/ngspice#g" "$spinit"
    mkdir -p "$root/bin"            # the wrapper last: its presence says the rest is there
    printf '#!/bin/sh\nSPICE_SCRIPTS=%s/usr/share/ngspice/scripts exec %s/usr/bin/ngspice "$@"\n' "$here" "$here" > "$root/bin/ngspice"
    chmod +x "$root/bin/ngspice"
}

extras=""
[ "$task" != run ] && extras="[test]"
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

if [ "$task" = test ] && command -v npm >/dev/null 2>&1 && [ ! -d .engines/wasm/node_modules/eecircuit-engine ]; then
    echo "setup: installing ngspice compiled to WebAssembly (npm eecircuit-engine) into .engines/wasm"
    mkdir -p .engines/wasm
    npm install --silent --prefix .engines/wasm eecircuit-engine >/dev/null 2>&1 \
        || echo "setup: npm could not install eecircuit-engine; its tests will skip" >&2
fi

if [ "$task" = test ] && [[ " $* " == *" deep"* ]]; then
    kicad9 || echo "setup: KiCad 9 could not be installed here; the KiCad schematic check will skip" >&2
fi

if [ "$task" = run ]; then
    mkdir -p out
    exec .venv/bin/analogy compare --csv out/default.csv --plot out/default.png "$@"
elif [ "$task" = engine ]; then
    # a machine that cannot fetch it (not Debian 12, no network) skips the pass and says so
    ngspice46 || { echo "setup: ngspice 46 could not be set up here, so there is no engine pass" >&2; exit 0; }
    lib="$(ls "$PWD"/.engines/ngspice-46/usr/lib/*/libngspice.so.0)"
    echo "setup: the SPICE tests against $("$PWD"/.engines/ngspice-46/bin/ngspice -v | grep -o 'ngspice-[0-9]*' | head -1)"
    ANALOGY_EXPECT_NGSPICE=46 PATH="$PWD/.engines/ngspice-46/bin:$PATH" NGSPICE_LIBRARY_PATH="$lib" \
        SPICE_SCRIPTS="$PWD/.engines/ngspice-46/usr/share/ngspice/scripts" \
        exec .venv/bin/python -m pytest -q -n 2 -m "ngspice and not deep" "$@"
elif [[ " $* " == *" deep"* ]]; then
    exec .venv/bin/python -m pytest -q "$@"     # the deep checks one at a time: each is minutes of one core
else
    # two processes (pytest-xdist): the suite's tests are independent; -n 0 runs them in one
    exec .venv/bin/python -m pytest -q -n 2 "$@"
fi
