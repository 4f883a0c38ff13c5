"""The paper-free core of labcli: the wire, the device, settling, the run engine, the run
file, the tables, the protocol loader, the simulated rig's plumbing, and the interface
(:mod:`labcli.core.paper`) through which a paper plugs in.

Nothing here imports a paper: each paper is a subpackage of :mod:`labcli.papers`,
found through :mod:`labcli.core.registry`.
"""
