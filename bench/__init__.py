"""The benchmarks: one `bench_*.py` script per family of figures the docs cite (docs/benchmarks.md lists
each figure, its script, its command and the machine it was measured on), the helpers they share in
`_*.py` modules, and in `experiments/` the one-off probes behind a written conclusion.

Every script answers `--help` without doing any work and prints the machine it measures on first
(`bench._timing.print_machine`). Run a script from the checkout's root with the package importable:
`PYTHONPATH=src:.:bench .venv/bin/python bench/bench_scale.py --help` (or `python -m bench.bench_scale`).
"""
