"""The shipped protocol files.

This folder is the one copy of labcli's shipped protocols: the files people read, copy and
edit.  Installed, it is the package ``labcli.protocols`` (``pyproject.toml`` maps the
package onto this folder), so ``--protocol takuma2014`` finds the same files in any
install; this file only makes the folder a package.
"""
