"""Spatial files (`mechanism = "spatial"`, docs/scenario-format.md#spatial-files):
the built-ins under scenarios/spatial/ state their python builders'
systems (tests/spatial_files.py wrote them) and their references agree
with the builders' to 1e-12; every refusal names the file, the key and
the reason; `mechval analyse` reports their structure."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from mechval.harness.cli import main
from mechval.model.scenario import ScenarioError
from mechval.reference.analysis import analyse, format_analysis
from mechval.reference.spatial.mechanism import spatial_solution
from mechval.scenarios import builtin_names, builtin_path, load, parse
from spatial_files import builtins

BUILTINS = {b.name: b for b in builtins()}
#: Issue 26: each file's reference agrees with its builder's to 1e-12,
#: here of the peak of each column's quantity class over the run.
AGREE = 1e-12
#: The files' numbers are the builders' (repr); frames are rebuilt from
#: their axes, and a symmetric tensor from six entries: a few ulps.
NUMBERS = 1e-15


def quantity(column: str) -> str:
    """The class a raw column is judged in: its suffix's kind."""
    suffix = column.rsplit(".", 1)[1]
    for prefix, kind in (("alpha", "alpha"), ("q", "attitude"), ("v", "velocity"), ("w", "omega"),
                         ("a", "acceleration"), ("F", "force"), ("M", "moment"), ("T", "moment")):
        if suffix.startswith(prefix):
            return kind
    return "position"


def test_the_spatial_built_ins_are_loadable_by_name_and_not_in_the_default_set():
    assert set(BUILTINS) == {p.stem for p in builtin_path("spatial/x").parent.glob("*.toml")}
    assert not any(name.startswith("spatial") for name in builtin_names())
    for name in BUILTINS:
        scenario = load(f"spatial/{name}")
        assert scenario.mechanism == "spatial" and scenario.description and scenario.name == name


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_a_built_in_file_states_its_builders_numbers(name):
    built, read = BUILTINS[name].builder.system, load(f"spatial/{name}").scene
    assert [b.name for b in read.bodies] == [b.name for b in built.bodies]
    # to an ulp: the builders compute with BLAS, whose kernels round the
    # last bit differently on other CPUs than on the one that wrote the files
    for a, b in zip(built.bodies, read.bodies):
        assert a.mass == b.mass
        assert np.allclose(a.com, b.com, rtol=NUMBERS, atol=0) and np.allclose(a.position, b.position, rtol=NUMBERS, atol=0)
        assert np.abs(a.inertia - b.inertia).max() <= NUMBERS * np.abs(a.inertia).max()
        assert np.allclose(a.rotation, b.rotation, rtol=0, atol=NUMBERS)
    for a, b in zip(built.joints, read.joints, strict=True):
        assert (a.name, a.kind, a.body_i, a.body_j, a.damping) == (b.name, b.kind, b.body_i, b.body_j, b.damping)
        assert np.allclose(a.point_i, b.point_i, rtol=NUMBERS, atol=0) and np.allclose(a.point_j, b.point_j,
                                                                                        rtol=NUMBERS, atol=0)
        assert np.allclose(a.frame_i, b.frame_i, rtol=0, atol=NUMBERS) and np.allclose(a.frame_j, b.frame_j, rtol=0,
                                                                                      atol=NUMBERS)
    assert [(d.joint, d.law) for d in built.drives] == [(d.joint, d.law) for d in read.drives]
    assert built.springs == read.springs or [vars(s) for s in built.springs] == [vars(s) for s in read.springs]
    assert built.gravity == read.gravity
    stated = BUILTINS[name].velocities
    assert set(read.velocities) == set(stated)
    for body, value in read.velocities.items():
        assert np.allclose(np.asarray(value, dtype=float), np.asarray(stated[body], dtype=float), rtol=NUMBERS, atol=0)


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_a_built_in_files_reference_agrees_with_its_builders(name):
    """The same solve (prescribed) or integration (torque-driven, free) of
    the file's system and of the builder's, at the file's samples."""
    builtin, scenario = BUILTINS[name], load(f"spatial/{name}")
    built = builtin.builder.system
    if builtin.velocities:
        import dataclasses
        built = dataclasses.replace(built, velocities=builtin.velocities)
    assert scenario.forward_dynamics == built.forward_dynamics
    t = scenario.time.t
    ours, theirs = spatial_solution(scenario.scene, t), spatial_solution(built, t)
    assert ours.structure == theirs.structure and ours.missing.keys() == theirs.missing.keys()
    # drives are named as in planar files ("drive", then their joints'), the builders' otherwise
    rename = {f"{b.name}.{q}": f"{a.name}.{q}" for a, b in zip(built.drives, scenario.scene.drives) for q in "TF"}
    columns = [c for c in ours.frame.columns if c != "t" and c not in ours.missing]
    peaks: dict[str, float] = {}
    for c in columns:
        kind = quantity(c)
        peaks[kind] = max(peaks.get(kind, 0.0), float(np.abs(theirs.frame[rename.get(c, c)]).max()))
    # Near a fold the solution amplifies the files' last-bit differences
    # from the builders (previous test): accelerations through the
    # Jacobian's inverse twice, so the bound grows with the square of the
    # solve's condition over its median (1 elsewhere). Measured on bennett
    # under OPENBLAS_CORETYPE=Sandybridge: 5.6e-12 of the peak beside its
    # folds, up to 2.7e-10 at 33× the median condition (bound there 1.1e-9).
    condition = theirs.condition if theirs.condition is not None else np.ones(len(t))
    bound = AGREE * np.maximum(1.0, condition / np.median(condition)) ** 2
    worst = {c: float((np.abs(ours.frame[c].to_numpy() - theirs.frame[rename.get(c, c)].to_numpy()) / bound).max())
             / max(peaks[quantity(c)], 1e-300) for c in columns}
    column = max(worst, key=worst.get)
    assert worst[column] <= 1.0, f"{column}: {worst[column]:.3g} of its bound (AGREE × condition² over its median)"


# --- refusals -----------------------------------------------------------------------------------

def document(name: str = "spherical-fourbar") -> dict:
    return tomllib.loads(builtin_path(f"spatial/{name}").read_text(encoding="utf-8"))


def refused(doc: dict) -> ScenarioError:
    with pytest.raises(ScenarioError) as caught:
        parse(doc, "bad.toml")
    error = caught.value
    assert str(error).count("\n") == 0 and str(error).startswith("bad.toml: ")
    return error


def edited(name: str, edit) -> dict:
    doc = copy.deepcopy(document(name))
    edit(doc)
    return doc


def _set(path: str, value):
    """An edit setting the dotted path (list indices as numbers) to value."""
    def edit(doc):
        *head, last = path.split(".")
        node = doc
        for part in head:
            node = node[int(part)] if part.isdigit() else node[part]
        node[int(last) if last.isdigit() else last] = value
    return edit


def _delete(path: str):
    def edit(doc):
        *head, last = path.split(".")
        node = doc
        for part in head:
            node = node[int(part)] if part.isdigit() else node[part]
        del node[int(last) if last.isdigit() else last]
    return edit


REFUSALS = [
    # (file, edit, key, words in the reason)
    ("spherical-fourbar", _set("colour", 1), "colour", "unknown key"),
    ("spherical-fourbar", _set("body.0.colour", 1), "body.input.colour", "unknown key"),
    ("spherical-fourbar", _set("body.0.mass", "1"), "body.input.mass", "expected a number"),
    ("spherical-fourbar", _set("body.0.mass", float("nan")), "body.input.mass", "must be finite"),
    ("spherical-fourbar", _set("body.0.com", [0.0, 1.0]), "body.input.com", "expected three finite numbers"),
    ("spherical-fourbar", _set("body.0.com", [0.0, 1.0, float("inf")]), "body.input.com[2]", "must be finite"),
    ("spherical-fourbar", _set("body.0.inertia", [1e-3, 1e-3, 1e-3, 0.0, 0.0, 2e-3]), "body.input.inertia",
     "not positive definite"),
    ("spherical-fourbar", _set("body.0.inertia", [1e-3, 1e-3, 3e-3, 0.0, 0.0, 0.0]), "body.input.inertia",
     "triangle inequality"),
    ("spherical-fourbar", _set("body.0.inertia", [1e-3, 1e-3, 0.0, 0.0, 0.0, 0.0]), "body.input.inertia",
     "positive definite"),
    ("spherical-fourbar", _set("body.1.name", "input"), "body[1].name", "a second body named 'input'"),
    ("spherical-fourbar", _set("body.1.name", "ground"), "body[1].name", "not a usable name"),
    ("spherical-fourbar", _set("joint.1.name", "A"), "joint[1].name", "a second joint named 'A'"),
    ("spherical-fourbar", _set("joint.0.axis", [0.0, 0.0, 0.0]), "joint.A.axis", "degenerate"),
    ("spherical-fourbar", _set("joint.0.reference", [0.0, 0.0, 2.0]), "joint.A.reference", "parallel to the axis"),
    ("spherical-fourbar", _delete("joint.1.axis"), "joint.B.axis", "missing value"),
    ("spherical-fourbar", _set("joint.0.type", "screw"), "joint.A.type", "must be one of"),
    ("spherical-fourbar", _set("joint.0.between", ["ground.A", "nobody.A"]), "joint.A.between", "unknown body"),
    ("spherical-fourbar", _set("joint.0.between", ["ground.A", "input.Z"]), "joint.A.between", "has no point"),
    ("spherical-fourbar", _set("joint.0.between", ["input.A", "input.B"]), "joint.A.between", "to itself"),
    ("spherical-fourbar", _set("drive.0.joint", "Z"), "drive[0].joint", "unknown joint"),
    ("spherical-fourbar", _set("drive", [{"joint": "A", "omega0": 1.0}, {"joint": "A", "omega0": 1.0}]),
     "drive[1].joint", "a second drive"),
    # mobility 1, two drives
    ("spherical-fourbar", _set("drive", [{"joint": "A", "omega0": 1.0}, {"joint": "D", "omega0": 1.0}]),
     "drive", "the mobility is 1"),
    # the output axis moved far off: the loop cannot close
    ("spherical-fourbar", _set("ground.D", [5.0, 0.0, 5.0]), "joint", "cannot close"),
    ("spherical-fourbar", _set("effects.gravity", [0.0, -9.81]), "effects.gravity", "three finite numbers"),
    ("spherical-fourbar", _set("assembly", {"input": {"axis": [0.0, 0.0, 1.0]}}), "assembly.input.angle",
     "go together"),
    ("spherical-fourbar", _set("assembly", {"input": {"rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                                                                   [0.0, 0.0, -1.0]]}}),
     "assembly.input.rotation", "reflection"),
    ("spherical-fourbar", _set("assembly", {"input": {"rotation": [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0],
                                                                   [0.0, 0.0, 1.0]]}}),
     "assembly.input.rotation", "not orthonormal"),
    ("spherical-fourbar", _set("assembly", {"input": {"quaternion": [0, 0, 0, 0]}}), "assembly.input.quaternion",
     "all four components are zero"),
    ("spherical-fourbar", _set("assembly", {"nobody": {}}), "assembly.nobody", "unknown key"),
    ("spherical-fourbar", _set("torque", [{"joint": "B", "torque": 1.0}]), "torque", "every degree of freedom"),
    ("spherical-fourbar", _set("torque", [{"joint": "A", "torque": 1.0}]), "torque.A.joint", "has a drive"),
    ("spherical-fourbar", _set("force", [{"type": "force", "body": "nobody", "force": [0, 0, 1]}]),
     "force[0].body", "unknown body"),
    ("spherical-fourbar", _set("drive.0.omega0", 1e7), "drive[0]", "beyond"),
    ("delta-robot", lambda doc: doc.update(drive=doc["drive"][:2]), "drive",
     "the mobility is 3 (rank of the joints' Jacobian, Grübler–Kutzbach 3) but 2 drives prescribe the motion; "
     "fewer drives than degrees of freedom make an integrated run"),
    ("delta-robot", lambda doc: doc.update(drive=doc["drive"][:2], initial={"platform": {"velocity": [0, 0, 0]}}),
     "initial.platform", "do not satisfy the joints"),
    ("rssr", _delete("joint.2.axis_j"), "joint.Q.axis_j", "second pin"),
    # the output pivot moved out of the coupler's reach: the run cannot be followed past t ≈ 1.41 s
    ("rssr", _set("ground.C", [0.0, 0.45, 0.1]), "time", "the loop cannot close at t = 1.4"),
    ("rssr", _set("joint.1.axis", [0.0, 0.0, 1.0]), "joint.P.axis", "unknown key"),
    ("heavy-top", _set("initial.top.velocity", [1.0, 0.0, 0.0]), "initial.top", "do not satisfy the joints"),
    ("heavy-top", _set("initial.nobody", {"omega": [0.0, 0.0, 1.0]}), "initial.nobody", "unknown key"),
    ("heavy-top", _set("initial.top", {}), "initial.top.velocity", "missing value"),
    ("heavy-top", _set("body.0.principal", [1e-3, 1e-3, 1e-3]), "body.top.inertia", "not both"),
    ("t-handle", _set("body.0.mass", 0.0), "body.body.mass", "must be positive"),
]


@pytest.mark.parametrize("name,edit,key,words", REFUSALS, ids=[f"{r[0]}-{r[2]}-{k}" for k, r in enumerate(REFUSALS)])
def test_bad_spatial_input_is_refused_naming_the_key(name, edit, key, words):
    error = refused(edited(name, edit))
    assert error.key == key and words in error.reason, (error.key, error.reason)


def test_inertia_by_principal_moments_and_axes():
    """`principal` about `principal_axes` is the tensor Σ Ik·ak·akᵀ."""
    doc = document("heavy-top")
    axes = np.array([[0.6, 0.8, 0.0], [-0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    body = doc["body"][0]
    del body["inertia"]
    body.update(principal=[2e-4, 3e-4, 4e-4], principal_axes=axes.tolist())
    I = parse(doc, "ok.toml").scene.bodies[0].inertia
    assert np.allclose(I, axes.T @ np.diag([2e-4, 3e-4, 4e-4]) @ axes, rtol=1e-15, atol=0)
    body["principal_axes"] = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    error = refused(doc)
    assert error.key == "body.top.principal_axes" and "not orthonormal" in error.reason
    body["principal_axes"] = axes.tolist()
    body["principal"] = [1e-4, 1e-4, 3e-4]
    error = refused(doc)
    assert error.key == "body.top.principal" and "triangle inequality" in error.reason


def test_the_three_ways_of_stating_a_rotation_agree():
    """The heavy top's tilt about x: as rows, axis and angle, quaternion."""
    doc = document("heavy-top")
    tilt = 0.5
    R = load("spatial/heavy-top").scene.bodies[0].rotation
    for rotation in ({"axis": [2.0, 0.0, 0.0], "angle": tilt},
                     {"quaternion": [np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0]}):
        doc["assembly"]["top"] = {"position": [0.0, 0.0, 0.0], **rotation}
        assert np.allclose(parse(doc, "ok.toml").scene.bodies[0].rotation, R, rtol=0, atol=1e-15), rotation


def test_a_bad_spatial_file_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    text = builtin_path("spatial/bricard").read_text(encoding="utf-8")
    path.write_text(text.replace('type = "revolute"', 'type = "helical"', 1), encoding="utf-8")
    assert main(["analyse", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mechval: error: {path}: joint.P0.type: must be one of") and err.count("\n") == 1


# --- mechval analyse ---------------------------------------------------------------------------------

def test_analyse_bricard_grubler_zero_mobility_one(capsys):
    """A04's stated facts: Grübler–Kutzbach 6·5 − 5·6 = 0, mobility 1, one
    redundant row; integrated over its run, the joints' Jacobian keeps its
    rank (no near-singular instant)."""
    a = analyse(load("spatial/bricard"))
    assert (a.grubler, a.mobility, a.redundant, a.bodies, a.joints, a.drives) == (0, 1, 1, 5, 6, 0)
    assert a.integrated and np.isfinite(a.condition_max) and not a.near_singular
    assert main(["analyse", "spatial/bricard"]) == 0
    out = capsys.readouterr().out
    assert "Grübler–Kutzbach 6·5 − 30 = 0" in out and "mobility            1" in out and "redundant           1" in out


def test_analyse_bennett_finds_its_folds():
    """Bennett's linkage: Grübler 6·3 − 4·5 = −2, mobility 1, three
    redundant rows. Driven from θ1 = 1 rad at 1 rad/s, it folds flat at
    θ1 = π and 2π (t = π − 1, 2π − 1): the rows the reference keeps turn
    ill-conditioned on either side of each fold, where it picks others
    (the condition it solves with peaks there, above 10× its median)."""
    scenario = load("spatial/bennett")
    a = analyse(scenario)
    assert (a.grubler, a.mobility, a.redundant) == (-2, 1, 3) and not a.integrated
    theta1_0 = BUILTINS["bennett"].builder.theta1_0
    peaks = np.array([t for t, _ in a.near_singular])
    for fold in (np.pi - theta1_0, 2 * np.pi - theta1_0):
        near = peaks[np.abs(peaks - fold) < 0.05]
        assert near.min() < fold < near.max(), (fold, peaks)
    assert len(peaks) == 4
    text = format_analysis(a)
    assert "near-singular       4 instants" in text and "Grübler–Kutzbach 6·3 − 20 = -2" in text


def test_the_docs_spatial_examples_load_and_run():
    """The ```toml spatial blocks of docs/scenario-format.md: complete
    spatial files; the example's stated velocities satisfy its joints."""
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "docs" / "scenario-format.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```toml spatial\n(.*?)^```", text, re.S | re.M)
    assert blocks
    for block in blocks:
        scenario = parse(tomllib.loads(block), "docs example")
        assert scenario.mechanism == "spatial" and scenario.forward_dynamics
        solution = spatial_solution(scenario.scene, scenario.time.t[:11])
        assert solution.facts["constraint_drift_max"] <= 1e-10 and np.isfinite(solution.frame.to_numpy()).all()


def test_export_refuses_a_spatial_file(capsys):
    assert main(["export", "spatial/bricard"]) == 2
    err = capsys.readouterr().err
    assert ": mechanism: `mechval export` writes a scene as a planar file" in err and err.count("\n") == 1


def test_named_axes_stand_for_their_vectors():
    """`axes` of a body (or the ground) named in a joint's `axis`,
    `reference`, `axis_j`, `reference_j` ("body.AXIS" of that side's body)."""
    doc = document("delta-robot")
    plain = parse(doc, "ok.toml").scene
    named = copy.deepcopy(doc)
    for joint in named["joint"]:
        body_i, body_j = (end.split(".")[0] for end in joint["between"])
        for key, body in (("axis", body_i), ("reference", body_i), ("axis_j", body_j), ("reference_j", body_j)):
            if key in joint:
                table = named.setdefault("ground", {}) if body == "ground" else \
                    next(b for b in named["body"] if b["name"] == body)
                table.setdefault("axes", {})[f"{joint['name']}_{key}"] = joint[key]
                joint[key] = f"{body}.{joint['name']}_{key}"
    read = parse(named, "ok.toml").scene
    for a, b in zip(plain.joints, read.joints, strict=True):
        assert np.array_equal(a.frame_i, b.frame_i) and np.array_equal(a.frame_j, b.frame_j), a.name
    named["joint"][1]["axis_j"] = "arm0.R0_axis"
    error = refused(named)
    assert error.key == "joint.E0.axis_j" and "an axis of 'rod0'" in error.reason
    named["joint"][1]["axis_j"] = "rod0.nothing"
    error = refused(named)
    assert error.key == "joint.E0.axis_j" and "'rod0' has no axis 'nothing'" in error.reason
