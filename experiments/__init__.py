"""The paper's experiments and the benchmarks, run as scripts (``python experiments/ablation.py``).

A package so that tests import them (``from experiments import ablation``) instead of
loading files by path; the repository root is on pytest's path (``pyproject.toml``).
"""
