"""The composition root: the only code that imports every package. Its parts: `cli` (the
command layer: flags and printing), `usecases` (the code behind each command), `experiments`
(the dissertation's figures, each with its results record and tables), `bench`, `results` (the
one registry of results sources, the claims, provenance), `params` (the one validation
layer) and `demo` (`make demo`: the main jobs, each the command a user would type)."""
