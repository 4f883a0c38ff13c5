"""Takuma, Takamine & Masuda, Actuators 2014: force and angle sensing from the pressures of a
2-DoF McKibben joint (Sections 2-3) and object stiffness by pushing (Section 4)."""
