"""Helpers of `benchmarks/bench_fleet.py`: robots, audit counting, the DaemonSet and CoralSystem runs."""
