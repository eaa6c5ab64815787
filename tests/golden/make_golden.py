"""Regenerate the golden ngspice outputs of the paper's five netlists (``netlists/*.cir``).

Run from the repository root with the ngspice executable on the path:

    python tests/golden/make_golden.py

Each netlist is run unchanged by ``ngspice -b`` through a control block that writes
the solution at ngspice's own time points to a binary raw file ``<name>.raw`` here
(not interpolated: the steps may be half the print step, where linear interpolation errs
more than the bound), with ``<name>.txt`` recording the ngspice
version. ``tests/test_golden.py`` checks them against the exact solution and against
the in-process run.
"""

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
NETLISTS = HERE.parent.parent / "netlists"


def main() -> int:
    ngspice = shutil.which("ngspice")
    if ngspice is None:
        print("make_golden: the ngspice executable is not on the path", file=sys.stderr)
        return 1
    version = subprocess.run([ngspice, "--version"], capture_output=True, text=True).stdout
    version = next((ln.strip("* ").strip() for ln in version.splitlines() if "ngspice-" in ln), "unknown")
    for cir in sorted(NETLISTS.glob("*.cir")):
        raw = HERE / f"{cir.stem}.raw"
        text = cir.read_text()
        # the netlist's own printing block is replaced by one that writes a raw file
        body = [ln for ln in text.split(".control")[0].splitlines() if ln.strip().lower() != ".end"]
        control = [".control", "set filetype=binary", "run", f"write {raw}", ".endc", ".end"]
        with tempfile.TemporaryDirectory() as tmp:
            deck = Path(tmp) / cir.name
            deck.write_text("\n".join(body + control) + "\n")
            res = subprocess.run([ngspice, "-b", str(deck)], capture_output=True, text=True, timeout=600)
        if res.returncode != 0 or not raw.exists():
            print(f"make_golden: ngspice failed on {cir.name}:\n{res.stderr}", file=sys.stderr)
            return 1
        (HERE / f"{cir.stem}.txt").write_text(f"{cir.name} run by {version}, at its own time points\n")
        print(f"wrote {raw.relative_to(HERE.parent.parent)} ({raw.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
