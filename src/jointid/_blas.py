"""Single-threaded BLAS for the many small dense problems of identification.

Force-state mapping and harmonic balance solve thousands of tiny systems (3x3 to 40x40).
A threaded BLAS wakes its worker threads for each of them; on a loaded machine that made
a 5x5 triangular solve take milliseconds instead of microseconds.  Running these parts
with one BLAS thread is faster and also makes the floating-point sums independent of
the thread count, so the same input gives bit-identical results on any machine.
"""

from __future__ import annotations

from functools import wraps

from threadpoolctl import ThreadpoolController

__all__ = ["single_threaded"]

_CONTROLLER: list = []  # created on first use (inspecting the loaded libraries costs ~10 ms)


def _controller() -> ThreadpoolController:
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


def single_threaded(func):
    """Decorator: run ``func`` with BLAS limited to one thread.

    The wrapper adds one frame: a warning raised in ``func`` for its caller needs
    ``stacklevel=3`` (two more for each helper level below it).
    """

    @wraps(func)
    def wrapper(*args, **kwargs):
        with _controller().limit(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper
