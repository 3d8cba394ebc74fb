"""Reproductions of the paper's experiments and the speed benchmarks."""
