"""The model: what a scene is. Scenario files become a `Scenario` (scenario,
scene), its `Mechanism` (mechanism, drive, linkages, dynamic_scene), with
the bounds of what mechval simulates (limits) and planar kinematics written
once (kinematics)."""
