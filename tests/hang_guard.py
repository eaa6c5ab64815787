"""A guard against hangs that no load can trip: speed is shown by benchmarks, never by a test."""

import threading

#: Seconds. A refusal takes milliseconds; only a hang (an exponent tower evaluated, an
#: expansion without end) reaches a minute, on any machine under any load.
HANG = 60.0


def finishes(call, limit: float = HANG):
    """*call()*'s result, re-raising what it raised; fails if it is still running after *limit* s."""
    out: dict = {}

    def target():
        try:
            out["value"] = call()
        except BaseException as exc:        # handed back to the caller's thread
            out["error"] = exc
    worker = threading.Thread(target=target, daemon=True)
    worker.start()
    worker.join(limit)
    assert not worker.is_alive(), f"still running after {limit:g} s: a hang"
    if "error" in out:
        raise out["error"]
    return out.get("value")
