"""Stage 6, studies built on :func:`morphlab.simulate` and :func:`morphlab.sensitivities`:
timing comparisons today; sweeps, optimization and uncertainty propagation next."""

from .timing import interleaved_times, median_time

__all__ = ["interleaved_times", "median_time"]
