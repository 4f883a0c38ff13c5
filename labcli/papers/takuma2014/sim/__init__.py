"""The simulated McKibben test bed: its physics, the rig behind the ADC, the pushed objects."""
