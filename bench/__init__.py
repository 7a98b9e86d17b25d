"""The benchmarks: one `bench_*.py` script per family of figures the docs cite (docs/benchmarks.md lists
each figure, its script, its command and the machine it was measured on), the helpers they share in
`_*.py` modules, and in `experiments/` the one-off probes behind a written conclusion.

Every script answers `--help` without doing any work and prints the machine it measures on first
(`bench._timing.print_machine`). Run a script as a module from the checkout's root, in the venv
`scripts/setup.sh` makes (the project installed in it): `.venv/bin/python -m bench.bench_scale --help`;
`-m` puts the checkout on the path, so no PYTHONPATH is needed.
"""
