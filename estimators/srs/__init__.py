"""Selective Random Sampling (seed §3.3–3.5): the novelty models and the SRS Tail policy."""

# The pick policies of §3.5.2.1 as the quantile of the novelty e they take. "Q3" and "Q2" are
# read as the upper and lower quartile (the text's "second and third quantile" is ambiguous).
PICKS = {"max": 1.0, "q3": 0.75, "med": 0.5, "q2": 0.25}
