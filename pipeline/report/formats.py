"""How the report prints a number with its interval, a share with its Wilson interval, and the
verdict an interval gives: the forms every table shares (``2.31 [1.90, 2.75]``, ``57.71% [55.49,
59.93]``, ``12/40 = 30.0% [18.1, 45.4]``), written once."""

from __future__ import annotations

from pipeline.stats import wilson_ci


def interval(lo: float, hi: float, digits: int = 2, scale: float = 1, sign: str = "") -> str:
    """``[lo, hi]``, the ends times ``scale`` (100: percent or points) with ``digits`` decimals;
    ``sign="+"`` prints the sign of each."""
    return f"[{scale * lo:{sign}.{digits}f}, {scale * hi:{sign}.{digits}f}]"


def estimate(
    value: float, lo: float, hi: float, digits: int = 2, scale: float = 1, sign: str = ""
) -> str:
    """``value [lo, hi]`` in the form of :func:`interval`."""
    return f"{scale * value:{sign}.{digits}f} {interval(lo, hi, digits, scale, sign)}"


def share(k: int, n: int, digits: int = 1) -> str:
    """``k/n = 30.0% [18.1, 45.4]``: the share of ``n`` independent outcomes with its 95% Wilson
    interval in percent; "" for no outcomes."""
    if not n:
        return ""
    return f"{k}/{n} = {100 * k / n:.{digits}f}% {interval(*wilson_ci(k / n, n), digits, 100)}"


def verdict(lo: float, hi: float) -> str:
    """The claims section's rule for one check: it holds when its interval lies above zero, does
    not hold when below, and is not resolved otherwise."""
    return "holds" if lo > 0 else "does not hold" if hi < 0 else "not resolved"


def combined(verdicts: list[str]) -> str:
    """The verdict of several checks together: it holds when each holds, does not hold when one
    does not, and is not resolved otherwise."""
    if "does not hold" in verdicts:
        return "does not hold"
    return "holds" if all(v == "holds" for v in verdicts) else "not resolved"
