"""The paper-free core of labcli: the wire, the device, settling, the run engine, the run
file, the tables, the protocol loader, the simulated rig's plumbing, and the interface
(:mod:`labcli.core.experiment`) through which an experiment plugs in.

Nothing here imports a paper: each paper is a subpackage of :mod:`labcli.experiments`,
found through :mod:`labcli.core.registry`.
"""
