"""The rPAM joint paper (2015): a 1-DoF revolute joint driven by two reverse pneumatic
artificial muscles; its stretch test, joint map and link optimisation."""
