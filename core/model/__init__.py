"""The model: what a scene is. Scenario files become a `Scenario` (scenario,
scene) of rigid bodies, joints and a drive (mechanism, drive), with planar
kinematics written once (kinematics). It imports nothing else of mechval:
the reference builds on it."""
