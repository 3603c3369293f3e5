"""Tail probabilities and quantiles of the chi-squared and Student t distributions.

The same special functions scipy.stats' `chi2` and `t` evaluate (scipy 1.17 `_sf`, `_isf`,
`_ppf`), called directly, so every p-value and interval is the same to the bit. Importing
scipy.stats for them cost each node and command about 0.9 s of its start (it pulls in
scipy.optimize, scipy.sparse and scipy.spatial), on every `ros2 run`.
Arguments are taken inside each distribution's support (x >= 0, dof > 0), as the callers
guard; outside it the special functions give nan.
"""

from scipy import special


def chi2_sf(x: float, dof: float) -> float:
    """P(X > x) for X chi-squared with dof degrees of freedom (`scipy.stats.chi2.sf`)."""
    return float(special.chdtrc(dof, x))


def chi2_isf(p: float, dof: float) -> float:
    """The x with P(X > x) = p, X chi-squared with dof degrees of freedom (`chi2.isf`)."""
    return float(special.chdtri(dof, p))


def t_sf(x: float, dof: float) -> float:
    """P(T > x) for T Student t with dof degrees of freedom (`scipy.stats.t.sf`)."""
    return float(special.stdtr(dof, -x))


def t_ppf(q: float, dof: float) -> float:
    """The x with P(T <= x) = q, T Student t with dof degrees of freedom (`t.ppf`)."""
    return float(special.stdtrit(dof, q))


def t_isf(p: float, dof: float) -> float:
    """The x with P(T > x) = p, T Student t with dof degrees of freedom (`t.isf`)."""
    return float(-special.stdtrit(dof, p))
