"""Speed and memory figures, printed as JSON (``python -m benchmarks``).

Each ``bench_*.py`` module defines ``run(quick: bool) -> dict`` returning its figures;
targets come from docs/performance.md and are reported beside the measurement, never asserted.
"""
