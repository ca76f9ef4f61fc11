"""Benchmarks: accuracy against the Cramer-Rao bound, solver speed."""
