"""Benchmarks, never timed tests: ``python -m toolpath.bench`` (``make bench``) writes ``reports/bench/*.json``."""
