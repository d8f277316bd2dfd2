"""Where the time of a direct sensitivity run goes: a cProfile of one run on the morphing
defaults, its own time (``tottime``) summed per stage of the library and per outside package.

Grouped by the file each function is defined in (``morphlab/<stage>/...``, NumPy, SciPy, Numba's
dispatch, the rest), so the grouping holds however the functions inside a stage are named. A
compiled kernel's time is charged to the Python function that called it (cProfile does not see
inside machine code), and the profiler inflates the share of many small Python calls.
"""

from __future__ import annotations

import cProfile
import pathlib
import pstats


def _group(filename: str) -> str:
    parts = pathlib.PurePath(filename).parts
    if "morphlab" in parts:
        rest = parts[len(parts) - 1 - parts[::-1].index("morphlab") + 1:]
        return f"morphlab.{rest[0].removesuffix('.py')}" if rest else "morphlab"
    for name in ("numpy", "scipy", "numba"):
        if name in parts:
            return name
    return "Python and other"


def direct_run(quick: bool = False) -> dict:
    """Profile one direct run of the morphing study (after an unprofiled one that loads the
    kernels); ``quick`` doubles the time step.

    Returns
    -------
    dict
        ``{"total_s": float, "seconds": {group: s}, "fractions": {group: share}}``, the groups
        being ``"morphlab.<stage>"``, ``"numpy"``, ``"scipy"``, ``"numba"`` and
        ``"Python and other"``.
    """
    import morphlab as ml

    from ..morphing import leading_edge as le

    settings = ml.Settings.of(le.SETTINGS, dt=2.0 * le.SETTINGS.dt) if quick else le.SETTINGS

    def run():
        return ml.sensitivities(le.build, dict(le.DEFAULTS), le.RESPONSES, method="direct",
                                settings=settings)

    run()
    prof = cProfile.Profile()
    prof.enable()
    run()
    prof.disable()
    seconds: dict = {}
    for (filename, _line, _func), row in pstats.Stats(prof).stats.items():
        g = _group(filename)
        seconds[g] = seconds.get(g, 0.0) + row[2]  # tottime: the function's own time
    total = sum(seconds.values())
    return {"total_s": total, "seconds": seconds,
            "fractions": {k: v / total for k, v in seconds.items()}}
