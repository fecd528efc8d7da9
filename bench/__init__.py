"""Benchmarks of portal-daq (``bench/run.py``: the service pipeline against a naive baseline)."""
