"""The rPAM model (Eqs. 1-7), its stretch-test and joint-map analysis, and the link optimiser."""
