"""Selective Random Sampling (seed §3.3–3.5): the novelty models (φ, ψ, ζ); the SR-phase Tail
that uses them is a Tail (`macrostate_mj.tails.srs`)."""
