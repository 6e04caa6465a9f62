"""A module a hostile config names as code: importing it or calling it leaves a trace the tests of
``test_code_in_configs.py`` look for."""

IMPORTED = True
CALLS: list[tuple] = []


def boom(*args, **kwargs):
    CALLS.append((args, kwargs))
    raise AssertionError("a config reached code it may not name")
