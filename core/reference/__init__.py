"""The exact reference, built on the model: the analytic `ReferenceAdapter`
(adapter); the one path from a scene to its `Mechanism` and closed form
(linkages, dynamic_scene) and the bounds of what is simulated (limits); the
closed forms of the four classic linkages (closed_forms); the general planar
solver (planar); forward dynamics and its consistent start (dynamics,
initial_state); Newton–Euler reactions (newton_euler) and each body's
resultant constraint load (resultants); `mechval analyse` (analysis)."""
