"""Scene report: one self-contained HTML page of a scene's run, with its circuit, plots, motion and netlist."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from datetime import datetime, timezone
from html import escape
from pathlib import Path

from ..files import write_text
from .. import __version__
from ..errors import InputError
from ..presets import DEFAULT_SOLVERS
from ..solvers.transient import netlist as make_netlist
from ..results.output import data_uri, figure_uri
from ..study.comparison import Comparison, compare

__all__ = ["SceneReport", "scene_report", "html_page"]

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.15em; margin-top: 1.8em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th { background: #f0f0f0; } caption { caption-side: top; text-align: left; color: #555; padding: 0.3em 0; }
.verdict { padding: 0.5em 0.8em; border-radius: 4px; }
.kept { background: #e6f4e6; } .broken { background: #fbe3e3; }
img { max-width: 100%; height: auto; } pre { background: #f7f7f7; padding: 0.8em; overflow: auto;
max-height: 28em; font-size: 0.8em; }
"""


def html_page(title: str, sections: list[tuple[str, str]]) -> str:
    """A whole HTML page: *title*, then each (heading, body) section; everything inline.

    Parameters
    ----------
    title : str
        The page's title and first heading.
    sections : list of (str, str)
        Headings and their HTML bodies.
    """
    body = "\n".join(f"<section><h2>{escape(h)}</h2>\n{b}\n</section>" for h, b in sections)
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>{escape(title)}</title>"
            f"<style>{_STYLE}</style></head>\n<body><h1>{escape(title)}</h1>\n{body}\n</body></html>\n")


@dataclass(eq=False)
class SceneReport:
    """A scene's run as one page.

    Attributes
    ----------
    scene : Scene
        What was run.
    comparison : Comparison
        Its solvers against the reference, every output against its own peak.
    netlist : str
        The netlist, with the settings of the run that SPICE made.
    html : str
        The page.
    """

    scene: object
    comparison: Comparison
    netlist: str
    html: str

    def __repr__(self) -> str:
        return f"<SceneReport {self.scene.name}: {len(self.html) / 1e3:.0f} kB page, {self.comparison!r}>"

    def _repr_html_(self) -> str:
        return self.html

    def save(self, directory) -> Path:
        """Write ``index.html`` into *directory* (made if need be); returns its path.

        Parameters
        ----------
        directory : str or Path
            The report's folder.
        """
        out = Path(directory)
        try:
            out.mkdir(parents=True, exist_ok=True)
            path = out / "index.html"
            write_text(path, self.html)
        except OSError as exc:
            raise InputError(f"cannot write the report into {out}: {exc.strerror or exc}") from None
        return path


def _verdict(c: Comparison) -> str:
    if not c.reference:
        return "<p class='verdict'>No reference ran, so no error is measured.</p>"
    flags = c.outside_bound()
    failed = "".join(f"<li>{escape(k)} failed: {escape(v)}</li>" for k, v in c.failures.items())
    if not flags and not c.failures:
        return (f"<p class='verdict kept'>Every output of every solver is within the {escape(c.preset)} preset's "
                f"bound {c.bound:g} of its own peak, against {escape(c.reference)}.</p>")
    lines = "".join(f"<li>{escape(s)} error on {escape(c.worst_output(s)[0])} is {e:.3g} of its own peak, "
                    f"above the bound {c.bound:g}</li>" for s, e in flags.items())
    return f"<div class='verdict broken'><ul>{lines}{failed}</ul></div>"


def _drawings(system) -> str:
    from ..circuit.diagram import draw
    with tempfile.TemporaryDirectory() as folder:
        paths = [p for p in draw(system, folder, "scene") if p.suffix == ".svg"]
        images = [(p.stem.removeprefix("scene_"), data_uri(p.read_bytes(), "image/svg+xml")) for p in sorted(paths)]
    return "\n".join(f"<figure><img src='{uri}' alt='{escape(what)}'></figure>" for what, uri in images)


def _provenance(scene, system) -> str:
    prov = system.provenance
    rows = [("scene", scene.name), ("content key", scene.key), ("robot", prov.robot),
            ("dynamics", scene.dynamics), ("preset", scene.preset), ("t_stop [s]", f"{scene.t_stop:g}"),
            ("configuration", ", ".join(f"{k} = {v:.6g}" for k, v in prov.configuration.items()) or "-"),
            ("parameters", ", ".join(f"{k} = {v:.6g}" for k, v in prov.parameters.items()) or "-"),
            ("units", ", ".join(prov.units) if prov.units else "-"),
            ("analogy", __version__), ("written", datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"))]
    body = "".join(f"<tr><th>{escape(k)}</th><td style='text-align:left'>{escape(str(v))}</td></tr>"
                   for k, v in rows)
    return f"<table>{body}</table>"


def scene_report(scene, *, animation: bool = True, frames: int = 48) -> SceneReport:
    """Run *scene*'s solvers once and lay out everything on one page.

    The page holds the verdict and table (every output against its own peak), the circuit
    drawings as SVG, the comparison plot, the motion of the circuit's run (the first
    successful solver's, SPICE's when it ran), the netlist as it ran, and the scene's key
    and provenance.

    Parameters
    ----------
    scene : Scene
        A validated scene.
    animation : bool
        Include the animation (its frames are most of the page's size).
    frames : int
        Frames of the animation.
    """
    system = scene.system()
    p = scene.settings
    solvers = scene.solvers or DEFAULT_SOLVERS
    comparison = compare(system, p, solvers)
    ran = getattr(comparison.results.get("spice"), "settings", None)
    title = f"analogy {scene.name}" + (f": {scene.description}" if scene.description else "")
    text = make_netlist(system, p, title=title, loosen=1.0 if ran is None else ran.loosen)
    sections = [("Result", _verdict(comparison) + comparison._repr_html_()),
                ("Circuit", _drawings(system)),
                ("Rates and errors", f"<img src='{figure_uri(comparison.plot())}' alt='rates and errors'>")]
    if animation:
        from ..study.motion import motion
        run = next((comparison.results[s] for s in ("spice", *comparison.results) if s in comparison.results
                    and comparison.results[s].success), None)
        if run is not None:
            shown = motion(system, run, frames, conventions=scene.model.conventions, model=scene.numeric_model())
            sections.append((f"Motion ({run.solver})", shown.to_jshtml()))
    link = data_uri(text.encode(), "text/plain")
    sections.append(("Netlist", f"<p><a download='{escape(scene.name)}.cir' href='{link}'>download</a> "
                                f"(runs as it is in <code>ngspice -b</code>)</p><pre>{escape(text)}</pre>"))
    sections.append(("Scene and provenance", _provenance(scene, system)))
    return SceneReport(scene, comparison, text, html_page(title, sections))
