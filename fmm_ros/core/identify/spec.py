"""What a friction fit is asked for: the search range of mu and the misfits it can minimise.

numpy-free, so the `fmm fit` options and the fitter's parameters can show these without
importing the fit.
"""

MU_BOUNDS = (1e-3, 1.0)
"""Default search range of the friction coefficient; a best fit on either end is a failure."""

MISFITS = ('time', 'frf')
"""What a fit minimises: the velocity's time residual, or the mobility's misfit in a band."""
