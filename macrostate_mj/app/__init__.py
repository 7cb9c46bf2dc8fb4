"""The composition root: the only code that imports every package (CLI, simulate, bench,
experiments, demo)."""
