"""ROS-free core of fmm_ros: importable and testable with numpy, scipy and numba alone.

Subpackages, in the order data flows through them: `physics` (Eq. 3 and its terms),
`signal` (records, capture, flags, FRFs, levels), `identify` (output-error fits, rig
identification), `diagnose` (where the model misses, and what it lacks). Each re-exports its
public API, so `from fmm_ros.core.identify import fit_friction` is the import users write.
"""
