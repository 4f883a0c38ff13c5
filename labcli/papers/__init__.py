"""The papers, one subpackage each, plugged into the core through :mod:`labcli.core.registry`."""
