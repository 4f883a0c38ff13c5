"""The simulated rPAM joint and stretch stand."""
