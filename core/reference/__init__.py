"""The exact reference: the analytic `ReferenceAdapter` (adapter), the closed
forms of the four classic linkages (closed_forms), the general planar solver
(planar), forward dynamics and its consistent start (dynamics,
initial_state), Newton–Euler reactions (newton_euler) and `mechval analyse`
(analysis)."""
