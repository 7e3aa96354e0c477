"""The general reference for any planar mechanism of rigid bodies, revolute
and prismatic joints: constraints, positions, forces, the linear algebra
and block elimination it shares (linear, tree), the solver, its side of a
scene (scene) and its `mechval analyse` (analysis)."""
