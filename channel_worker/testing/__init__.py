"""Helpers for tests and benchmarks only (exact references); the pipeline never imports them."""
