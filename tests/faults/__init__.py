"""Fault cases by area (a package so that pytest puts ``tests/`` on the path: ``entry``, ``fakes``)."""
