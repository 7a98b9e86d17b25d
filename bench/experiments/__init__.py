"""One-off probes: each supports one written conclusion of the docs (README.md here says which and where);
they are kept so that conclusion can be checked again, not run as benchmarks."""
