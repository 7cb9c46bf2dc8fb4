"""The simulated ant colony: behaviour, nest model, colony simulation."""
