"""The robot chain: scenarios, world assembly, motion rules, planners, simulation loop and
physics health."""
