"""One PNG that tiles every picture a test run wrote, so that all of them can be looked at together."""

from pathlib import Path

import numpy as np

THUMB = 360          # widest thumbnail side [px]
COLUMNS = 6


def thumbnail(path: Path) -> np.ndarray:
    """The image at *path*, RGB, shrunk by an integer stride to at most THUMB pixels wide or high."""
    import matplotlib.image
    image = matplotlib.image.imread(path)
    if image.ndim == 2:
        image = np.stack([image] * 3, axis=-1)
    stride = max(1, int(np.ceil(max(image.shape[:2]) / THUMB)))
    return image[::stride, ::stride, :3]


def contact_sheet(paths, target: Path) -> Path:
    """Tile the images at *paths* (each once by file name) into *target*, each titled with its name."""
    from matplotlib.figure import Figure
    unique = {}
    for p in paths:
        unique.setdefault(p.name, p)
    items = sorted(unique.items())
    rows = -(-len(items) // COLUMNS)
    fig = Figure(figsize=(COLUMNS * 3.2, rows * 2.9), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, COLUMNS, squeeze=False)).ravel()
    for ax in axes:
        ax.set_axis_off()
    for ax, (name, path) in zip(axes, items):
        try:
            ax.imshow(thumbnail(path))
        except (OSError, ValueError, SyntaxError):
            ax.text(0.5, 0.5, "unreadable", ha="center", transform=ax.transAxes)
        ax.set_title(name, fontsize=7)
    fig.suptitle(f"{len(items)} pictures written by the test run", fontsize=12)
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=90)
    return target
