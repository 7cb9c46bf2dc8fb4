"""Infrastructure every layer may use: errors, atomic files, manifests, progress, paths and
parallel tasks."""
