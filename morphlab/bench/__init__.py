"""The benchmark suite (``python -m morphlab.bench``); imported by nothing in the library."""
