"""Models and solids in scenes: loading each format, node sites, bad input as diagnostics."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.frontend import run_frontend
from mtlc.geometry import load, solids
from mtlc.geometry.model import place_nodes, placement, rotation_xyz
from mtlc.passes.lower import frame_matrix

HEADER = "use stdlib.actions\nuse stdlib.elements\n"


def panel_scene() -> trimesh.Scene:
    """A 60 x 40 cm panel (y up, facing +Z) with a marker node `bolt_1` at (20, 15, 1) cm whose
    +Y axis is turned to +Z (rotated -90 deg about X... i.e. its normal points out of the panel)."""
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box((0.6, 0.4, 0.01)), node_name="panel")
    m = np.eye(4)
    m[:3, :3] = trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0])[:3, :3]
    m[:3, 3] = [0.2, 0.15, 0.01]
    scene.graph.update(frame_to="bolt_1", frame_from=scene.graph.base_frame, matrix=m)
    return scene


def compile_front(tmp_path: Path, scene: str, body: str = "    walk_to(front)\n"):  # type: ignore[no-untyped-def]
    path = tmp_path / "main.mtask"
    path.write_text(
        f"{HEADER}scene bay {{\n{scene}    site front at (0, 0, 50) cm\n}}\n"
        f"task t {{\n    scene bay\n{body}}}\n",
        encoding="utf-8",
    )
    return run_frontend([path])


def codes(program) -> list[str]:  # type: ignore[no-untyped-def]
    return [d.code for d in program.diagnostics]


def test_glb_nodes_become_sites_with_the_node_y_axis_as_normal(tmp_path: Path) -> None:
    panel_scene().export(tmp_path / "panel.glb")
    program = compile_front(
        tmp_path,
        '    model p "panel.glb" at (0, 100, 80) cm\n    site b = p.bolt_1\n    sites from p\n',
        "    walk_to(front)\n    reach(right, b)\n    reach(right, bolt_1)\n",
    )
    assert codes(program) == []
    sites = {s.name: s for s in program.timelines[0].sites}
    assert np.allclose(sites["b"].position, (0.2, 1.15, 0.81))
    assert np.allclose(sites["b"].normal, (0, 0, 1))
    assert sites["bolt_1"].position == sites["b"].position
    (model,) = program.timelines[0].models
    assert model.name == "p" and model.source == "panel.glb" and len(model.sha256) == 64
    assert model.faces.shape == (12, 3) and model.faces.dtype == np.int64
    assert np.allclose(model.vertices.min(axis=0), (-0.3, 0.8, 0.795))


@pytest.mark.parametrize("suffix", ["stl", "obj", "glb", "gltf"])
def test_each_format_loads(tmp_path: Path, suffix: str) -> None:
    mesh = trimesh.creation.box((1.0, 2.0, 3.0))
    mesh.export(tmp_path / f"m.{suffix}")
    units = " units mm up z" if suffix in ("stl", "obj") else ""
    program = compile_front(tmp_path, f'    model m "m.{suffix}"{units}\n')
    assert codes(program) == []
    (model,) = program.timelines[0].models
    extent = model.vertices.max(axis=0) - model.vertices.min(axis=0)
    expected = (0.001, 0.003, 0.002) if units else (1.0, 2.0, 3.0)  # up z: file z is scene y
    assert np.allclose(extent, expected)
    assert model.triangles == 12


def test_stl_without_units_and_glb_with_units_are_mt0212(tmp_path: Path) -> None:
    trimesh.creation.box().export(tmp_path / "m.stl")
    trimesh.creation.box().export(tmp_path / "m.glb")
    assert codes(compile_front(tmp_path, '    model m "m.stl"\n')) == ["MT0212"]
    assert codes(compile_front(tmp_path, '    model m "m.glb" units mm\n')) == ["MT0212"]


BAD_FILES: dict[str, tuple[str, bytes | None, str]] = {
    "missing": ("gone.glb", None, "MT0005"),
    "garbage glb": ("bad.glb", b"glTF\x02\x00\x00\x00garbage", "MT0006"),
    "empty stl": ("empty.stl", b"", "MT0006"),
    "text as stl": ("notes.stl", b"solid a\nendsolid a\n", "MT0006"),
    "wrong kind": ("bay.step", b"ISO-10303-21;", "MT0006"),
    "escaping": ("../outside.glb", None, "MT0008"),
    "absolute": ("/etc/passwd.glb", None, "MT0008"),
    "drive": ("C:/cad/bay.glb", None, "MT0008"),
    "empty path": ("", None, "MT0005"),
    "nul in path": ("a\\u{0}b.glb", None, "MT0005"),
    "folder": (".", None, "MT0006"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_model_files_are_diagnostics_at_the_model_line(tmp_path: Path, case: str) -> None:
    name, data, code = BAD_FILES[case]
    if data is not None:
        (tmp_path / name).write_bytes(data)
    units = " units mm" if name.endswith((".stl", ".step")) else ""
    program = compile_front(tmp_path, f'    model m "{name}"{units}\n')
    found = [(d.code, d.span.line, d.span.column) for d in program.diagnostics]
    assert found == [(code, 4, 5)], found


def test_a_folder_is_mt0005(tmp_path: Path) -> None:
    (tmp_path / "dir.glb").mkdir()
    assert codes(compile_front(tmp_path, '    model m "dir.glb"\n')) == ["MT0005"]


def test_unknown_node_is_mt0211_with_a_suggestion(tmp_path: Path) -> None:
    panel_scene().export(tmp_path / "panel.glb")
    program = compile_front(tmp_path, '    model p "panel.glb"\n    site b = p.bolt_2\n')
    (d,) = program.diagnostics
    assert (d.code, d.span.line, d.span.column) == ("MT0211", 5, 16)
    assert "bolt_1" in (d.help or "")


def test_a_model_in_mm_declared_metres_is_mt0408(tmp_path: Path) -> None:
    trimesh.creation.box((2000.0, 1000.0, 500.0)).export(tmp_path / "bay.stl")
    program = compile_front(tmp_path, '    model bay "bay.stl" units m\n')
    assert [(d.code, d.span.line) for d in program.diagnostics] == [("MT0408", 4)]
    assert codes(compile_front(tmp_path, '    model bay "bay.stl" units mm\n')) == []


def test_too_many_triangles_is_mt0007(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    trimesh.creation.icosphere(subdivisions=3).export(tmp_path / "ball.stl")  # 1280 triangles
    monkeypatch.setattr(load, "MAX_TRIANGLES", 1000)
    load._CACHE.clear()
    program = compile_front(tmp_path, '    model ball "ball.stl" units cm\n')
    assert codes(program) == ["MT0007"]


def test_a_million_triangles_load_as_arrays(tmp_path: Path) -> None:
    """1 M triangles: read and placed without a loop over triangles (speed: bench, not here)."""
    n = 1_000_000
    rng = np.random.default_rng(0)
    tris = rng.uniform(-0.5, 0.5, (n, 3, 3)).astype(np.float32)
    data = bytearray(80) + np.uint32(n).tobytes()
    record = np.zeros(n, dtype=[("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    record["v"] = tris
    (tmp_path / "big.stl").write_bytes(bytes(data) + record.tobytes())
    program = compile_front(tmp_path, '    model big "big.stl" units m\n')
    assert codes(program) == []
    assert program.timelines[0].models[0].triangles == n


def test_solids_are_closed_and_placed(tmp_path: Path) -> None:
    program = compile_front(
        tmp_path,
        "    box b size (20, 10, 4) cm at (0, 100, 50) cm rotate (0, 90, 0) deg\n"
        "    cylinder c radius 2 cm length 50 cm axis (1, 0, 0) at (0, 80, 60) cm\n"
        "    plate p size (60, 40, 1) cm at (0, 120, 110) cm normal (0, 0, -1) opening round 10 cm\n"
        "    plate q size (60, 40, 1) cm at (0, 120, 90) cm opening rect (20, 10) cm\n",
    )
    assert codes(program) == []
    models = {m.name: m for m in program.timelines[0].models}
    for m in models.values():
        mesh = trimesh.Trimesh(m.vertices, m.faces)
        assert mesh.is_watertight and mesh.volume > 0, m.name
    box = models["b"].vertices
    assert np.allclose(box.max(axis=0) - box.min(axis=0), (0.04, 0.10, 0.20))  # turned about Y
    cyl = models["c"].vertices
    assert np.allclose(cyl.max(axis=0) - cyl.min(axis=0), (0.5, 0.04, 0.04), atol=1e-3)
    plate = trimesh.Trimesh(models["p"].vertices, models["p"].faces)
    assert plate.volume == pytest.approx(0.6 * 0.4 * 0.01 - math.pi * 0.05**2 * 0.01, rel=0.01)
    assert models["q"].parameters["opening"] == {"shape": "rect", "size": (0.2, 0.1)}
    # the opening is open: a point at the plate's centre is outside the solid
    assert not plate.contains([[0.0, 1.2, 1.1]])[0]


def test_an_opening_larger_than_its_plate_is_mt0309(tmp_path: Path) -> None:
    program = compile_front(tmp_path, "    plate p size (20, 20, 1) cm opening round 30 cm\n")
    assert [(d.code, d.span.line) for d in program.diagnostics] == [("MT0309", 4)]


def test_clause_checks(tmp_path: Path) -> None:
    def check(line: str) -> list[str]:
        return codes(compile_front(tmp_path, line))

    assert check("    box b size (1, 1) m\n") == ["MT0309"]
    assert check("    box b size (1, 1, 1) s\n") == ["MT0302"]
    assert check("    plate p size (1, 1, 0.01) m opening oval 5 cm\n") == ["MT0212"]
    assert check("    cylinder c radius 1 cm\n") == ["MT0212"]
    assert check("    box b size (1, 1, 1) m\n    box b size (1, 1, 1) m\n") == ["MT0202"]
    assert check("    box b size (1, 1, 1) m\n    site x = c.y\n") == ["MT0201"]
    assert check("    sites from nothing\n") == ["MT0201"]


def test_rotation_matches_a_sites_frame() -> None:
    for angles in [(0.3, -1.2, 2.0), (math.pi, 0, math.pi / 2)]:
        assert np.allclose(rotation_xyz(angles), frame_matrix(angles))


def test_files_without_models_do_not_import_trimesh(tmp_path: Path) -> None:
    import subprocess
    import sys

    code = (
        "import sys; from pathlib import Path; from mtlc.frontend import run_frontend; "
        f"p = run_frontend([Path({str(tmp_path / 'main.mtask')!r})]); "
        "assert not p.diagnostics, p.diagnostics; print('trimesh' in sys.modules)"
    )
    compile_front(tmp_path, "    box b size (1, 1, 1) m at (3, 0, 0) m\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@settings(max_examples=40, deadline=None)
@given(
    st.tuples(*[st.floats(-5, 5) for _ in range(3)]),
    st.tuples(*[st.floats(-180, 180) for _ in range(3)]),
    st.sampled_from(["mm", "cm", "m"]),
    st.sampled_from(["x", "y", "z"]),
    st.tuples(*[st.floats(-300, 300) for _ in range(3)]),
)
def test_node_sites_follow_any_placement(at, rotate, units, up, node) -> None:  # type: ignore[no-untyped-def]
    """A node's site is the node's origin through units, up axis, rotation and offset, and
    its normal the node's +Y turned by the same rotation; going back recovers the node."""
    scale = {"mm": 0.001, "cm": 0.01, "m": 1.0}[units]
    frame = np.eye(4)
    frame[:3, 3] = node
    matrix = placement(at, tuple(math.radians(a) for a in rotate), scale, up)
    ((position, normal),) = place_nodes(matrix, {"n": frame}).values()
    back = np.linalg.solve(matrix[:3, :3], position - np.asarray(at))
    assert np.allclose(back, node, atol=1e-6)
    assert math.isclose(float(np.linalg.norm(normal)), 1.0)
    assert np.allclose(normal, matrix[:3, :3] @ [0, 1, 0] / scale, atol=1e-9)


def test_solid_meshes_are_outward() -> None:
    for vertices, faces in (
        solids.box((1, 2, 3)),
        solids.cylinder(0.1, 1.0),
        solids.plate((0.6, 0.4, 0.01), ("round", 0.1)),
        solids.plate((0.6, 0.4, 0.01), ("rect", (0.2, 0.1))),
    ):
        mesh = trimesh.Trimesh(vertices, faces)
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0


def test_ir_json_and_jackscript_carry_the_models(tmp_path: Path) -> None:
    """The IR names each model's file and hash (each solid's parameters); the JackScript loads
    the file through the mapping table's LoadModel, its path a string literal, never code."""
    import json

    from mtlc.cli import main

    panel_scene().export(tmp_path / "it's.glb")
    src = tmp_path / "main.mtask"
    src.write_text(
        f'{HEADER}scene bay {{\n    model p "it\'s.glb" at (0, 100, 80) cm\n'
        "    box b size (10, 10, 10) cm at (1, 0, 0) m\n    sites from p\n"
        "    site front at (0, 0, 50) cm\n}\ntask t {\n    scene bay\n    walk_to(front)\n"
        "    reach(right, bolt_1)\n}\n",
        encoding="utf-8",
    )
    assert (
        main(
            ["compile", str(src), "--target", "ir", "--format", "json", "-o", str(tmp_path / "ir")]
        )
        == 0
    )
    (ir_file,) = (tmp_path / "ir").iterdir()
    models = json.loads(ir_file.read_text(encoding="utf-8"))["scene"]["models"]
    assert [(m["name"], m["kind"]) for m in models] == [("p", "model"), ("b", "box")]
    assert models[0]["path"] == "it's.glb" and len(models[0]["sha256"]) == 64
    assert models[0]["transform"][1][3] == 1.0 and models[1]["size"] == [0.1, 0.1, 0.1]
    assert main(["compile", str(src), "-o", str(tmp_path / "js")]) == 0
    script = (tmp_path / "js" / "main.py").read_text(encoding="utf-8")
    assert "LoadModel(\"it's.glb\", name='p', transform=((100.0, 0.0, 0.0, 0.0)," in script
    compile(script, "main.py", "exec")


@settings(max_examples=25, deadline=None)
@given(
    st.tuples(*[st.integers(-300, 300) for _ in range(3)]),
    st.tuples(*[st.integers(-180, 180) for _ in range(3)]),
)
def test_a_node_site_written_in_a_file_follows_the_model(at, rotate) -> None:  # type: ignore[no-untyped-def]
    """Through the whole front end: the site `bolt_1` of a placed glb is where scipy's intrinsic
    X-Y-Z rotation and the offset put the node, with the node's +Y turned likewise."""
    import tempfile

    from scipy.spatial.transform import Rotation

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        panel_scene().export(folder / "panel.glb")
        vec = ", ".join(str(c) for c in at)
        rot = ", ".join(str(c) for c in rotate)
        program = compile_front(
            folder,
            f'    model p "panel.glb" at ({vec}) cm rotate ({rot}) deg\n    site b = p.bolt_1\n',
            "    walk_to(front)\n    look(b)\n",
        )
    assert codes(program) == []
    site = next(s for s in program.timelines[0].sites if s.name == "b")
    turn = Rotation.from_euler("XYZ", rotate, degrees=True)
    expected = turn.apply([0.2, 0.15, 0.01]) + np.asarray(at) / 100
    assert np.allclose(site.position, expected, atol=1e-9)
    assert np.allclose(site.normal, turn.apply([0, 0, 1]), atol=1e-9)


def test_a_gltf_buffer_outside_the_folder_is_not_read(tmp_path: Path) -> None:
    """A .gltf's buffer URI leading out of the model's folder is refused (trimesh's resolver
    stays inside its root): MT0008, not the outside file's bytes."""
    import json

    inner = tmp_path / "proc"
    inner.mkdir()
    trimesh.creation.box().export(inner / "m.gltf")
    doc = json.loads((inner / "m.gltf").read_text(encoding="utf-8"))
    buffer = next(iter(doc["buffers"]))
    (tmp_path / "secret.bin").write_bytes(b"\0" * buffer["byteLength"])
    buffer["uri"] = "../secret.bin"
    (inner / "m.gltf").write_text(json.dumps(doc), encoding="utf-8")
    assert codes(compile_front(inner, '    model m "m.gltf"\n')) == ["MT0008"]


def test_an_edited_model_file_is_read_again(tmp_path: Path) -> None:
    """`mtlc serve` recompiles in one process: a changed file is read anew, one version kept."""
    trimesh.creation.box().export(tmp_path / "m.stl")
    first = compile_front(tmp_path, '    model m "m.stl" units cm\n').timelines[0].models[0]
    trimesh.creation.icosphere(subdivisions=1).export(tmp_path / "m.stl")
    second = compile_front(tmp_path, '    model m "m.stl" units cm\n').timelines[0].models[0]
    assert (first.triangles, second.triangles) == (12, 80)
    assert first.sha256 != second.sha256
    assert sum(key.endswith("m.stl") for key in load._CACHE) == 1
