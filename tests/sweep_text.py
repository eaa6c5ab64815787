"""The text of a small sweep file over the default arm, shared by the batch, store, orphan and cluster tests."""

#: The base scene: serial2 under a unit step on joint 1, SPICE and exact at the fast preset.
HEAD = """name = "arm"
[model]
robot = "serial2"
[inputs]
forces = [1, 0]
t_stop = 10
[solvers]
use = ["spice", "exact"]
preset = "fast"
"""


def sweep_text(count: int, axes: str = "q2 = [-3.0, 3.0]\n", group_size: int = 20) -> str:
    """A random design of *count* scenes over *axes* (TOML lines of ``[sweep.axes]``)."""
    return (HEAD + f'[sweep]\nmethod = "random"\ncount = {count}\nseed = 3\ngroup_size = {group_size}\n'
            f"[sweep.axes]\n{axes}")
