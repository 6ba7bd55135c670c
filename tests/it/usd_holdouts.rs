//! USD meshes as holdouts (issue 50): a `Mesh` prim of a `.usda` placed by its parent's
//! transform is the same holdout, bit for bit, as the OBJ of the same placed triangles; a
//! `.usdc` usd-core writes reads back to usd-core's own world-space points; a mesh nephele
//! cannot use is an error located at the scene's `holdouts[i].mesh` or `holdouts[i].prim`.

use std::process::Command;

use glam::DVec3;
use nephele::scene;
use nephele::scene::file::usd_mesh;

use crate::cli_support::nephele_in;
use crate::exr_support;
use crate::readers_support::skip_or_fail;
use crate::temp_support::temp_dir;

fn scene_text(holdouts: &str) -> String {
    format!(
        "Scene(target: Model(\"builtin:cumulus\"),\n  shot: (width: 48, height: 27, fps: 4, \
         seconds: 0.25),\n  holdouts: [{holdouts}],\n  ground: (height: -1.0),\n  \
         output: (dir: \"out\", name: \"h\", formats: [Exr]))"
    )
}

/// A box `[-1, 1]³` as six quads (outward), its points and face indices.
fn unit_box() -> (Vec<DVec3>, Vec<[u32; 4]>) {
    let points = (0..8)
        .map(|i| {
            let c = |bit: u32| if i & bit != 0 { 1.0 } else { -1.0 };
            DVec3::new(c(1), c(2), c(4))
        })
        .collect();
    let faces = vec![
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    (points, faces)
}

/// The box as a `.usda`: `/World` translated, `/World/box` scaled (a wide, low slab).
fn box_usda() -> String {
    let (points, faces) = unit_box();
    let points: Vec<String> = points
        .iter()
        .map(|p| format!("({}, {}, {})", p.x, p.y, p.z))
        .collect();
    let indices: Vec<String> = faces.iter().flatten().map(|i| i.to_string()).collect();
    format!(
        "#usda 1.0\n(\n    defaultPrim = \"World\"\n)\n\ndef Xform \"World\"\n{{\n    \
         double3 xformOp:translate = (0.5, 0, -0.25)\n    \
         uniform token[] xformOpOrder = [\"xformOp:translate\"]\n\n    \
         def Mesh \"box\"\n    {{\n        \
         int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n        \
         int[] faceVertexIndices = [{}]\n        \
         point3f[] points = [{}]\n        \
         float3 xformOp:scale = (6, 6, 0.5)\n        \
         uniform token[] xformOpOrder = [\"xformOp:scale\"]\n    }}\n\n    \
         def Xform \"cam\"\n    {{\n    }}\n}}\n",
        indices.join(", "),
        points.join(", ")
    )
}

/// The same box, placed by hand, as an OBJ (its quads as faces).
fn box_obj() -> String {
    let (points, faces) = unit_box();
    let mut obj = String::new();
    for p in points {
        let q = p * DVec3::new(6.0, 6.0, 0.5) + DVec3::new(0.5, 0.0, -0.25);
        obj += &format!("v {} {} {}\n", q.x, q.y, q.z);
    }
    for f in faces {
        obj += &format!("f {} {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1, f[3] + 1);
    }
    obj
}

/// The box's `.usda` and the OBJ of the same placed quads make the same holdout: the same
/// provenance key (the placed triangles' bits) and the same rendered frame, bit for bit.
#[test]
fn a_usda_holdout_is_the_same_holdout_as_its_obj() {
    let dir = temp_dir("usd-holdout");
    std::fs::write(dir.join("set.usda"), box_usda()).unwrap();
    std::fs::write(dir.join("set.obj"), box_obj()).unwrap();
    let transform = "transform: (up: Z, translate: (0.0, -0.3, 0.0)), shadows: true";
    let mut keys = Vec::new();
    let mut frames = Vec::new();
    for (name, holdout) in [
        ("obj", format!("(mesh: \"set.obj\", {transform})")),
        ("usd", format!("(mesh: \"set.usda\", {transform})")),
        (
            "prim",
            format!("(mesh: \"set.usda\", prim: \"/World/box\", {transform})"),
        ),
    ] {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        for f in ["set.usda", "set.obj"] {
            std::fs::copy(dir.join(f), sub.join(f)).unwrap();
        }
        std::fs::write(sub.join("h.ron"), scene_text(&holdout)).unwrap();
        let loaded = scene::load_scene(&sub.join("h.ron")).unwrap();
        keys.push(loaded.surfaces.expect("surfaces").key());
        let out = nephele_in(&sub).args(["render", "h.ron"]).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let layer = exr_support::read_first_layer(&sub.join("out/h_0001.exr"));
        let channels: Vec<(String, Vec<f32>)> = layer
            .channel_data
            .list
            .iter()
            .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
            .collect();
        frames.push(channels);
    }
    assert_eq!(keys[0], keys[1], "the USD holdout's key is the OBJ's");
    assert_eq!(keys[0], keys[2], "`prim` names the same mesh");
    let (_, holdout) = frames[0]
        .iter()
        .find(|(n, _)| n == "holdout.A")
        .expect("a holdout layer");
    assert!(
        holdout.iter().any(|&a| a > 0.0),
        "the holdout covers part of the frame"
    );
    for f in &frames[1..] {
        assert!(
            f == &frames[0],
            "the USD holdout's frame is the OBJ's, bit for bit"
        );
    }
}

/// usd-core writes a `.usdc` with a mesh (a quad, a triangle, a pentagon) under a rotated,
/// scaled, translated parent; nephele reads the same world-space points (to float precision)
/// and the faces split as fans; the scene loads it by `prim`.
#[test]
fn a_usd_core_usdc_mesh_reads_back_in_world_space() {
    let Some(python) = crate::usd_camera::usd_python() else {
        return;
    };
    let dir = temp_dir("usd-holdout-core");
    let stage = dir.join("set.usdc");
    let script = r#"
import json, sys
try:
    from pxr import Usd, UsdGeom, Gf
except ImportError as e:
    print(e, file=sys.stderr); sys.exit(3)
stage = Usd.Stage.CreateNew(sys.argv[1])
rig = UsdGeom.Xform.Define(stage, "/World/rig")
rig.AddTranslateOp().Set(Gf.Vec3d(1.5, -2.0, 0.25))
rig.AddRotateXYZOp().Set(Gf.Vec3f(10.0, 35.0, -20.0))
rig.AddScaleOp().Set(Gf.Vec3f(2.0, 1.0, 0.5))
mesh = UsdGeom.Mesh.Define(stage, "/World/rig/hill")
mesh.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.5, 0.0))
pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 1), (3, 1, 1), (3, 2, 2), (2.5, 3, 1), (2, 2, 1)]
mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
mesh.CreateFaceVertexCountsAttr([4, 3, 5])
mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 1, 4, 2, 4, 5, 6, 7, 8])
UsdGeom.Xform.Define(stage, "/World/other")
stage.GetRootLayer().Save()
m = mesh.ComputeLocalToWorldTransform(Usd.TimeCode.Default())
world = [list(m.Transform(Gf.Vec3d(*p))) for p in pts]
print(json.dumps(world))
"#;
    let run = Command::new(&python)
        .args(["-c", script])
        .arg(&stage)
        .output()
        .unwrap();
    if run.status.code() == Some(3) {
        skip_or_fail("usd-core", String::from_utf8_lossy(&run.stderr).trim());
        return;
    }
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let want: Vec<[f64; 3]> = serde_json::from_slice(&run.stdout).unwrap();
    for prim in [Some("/World/rig/hill"), None] {
        let mesh = usd_mesh::read(&stage, prim).unwrap();
        assert_eq!(mesh.positions.len(), want.len());
        for (got, want) in mesh.positions.iter().zip(&want) {
            let want = DVec3::from_array(*want);
            assert!(
                (*got - want).length() < 1e-5 * (1.0 + want.length()),
                "{got} vs usd-core {want}"
            );
        }
        assert_eq!(
            mesh.triangles,
            vec![
                [0, 1, 2],
                [0, 2, 3],
                [1, 4, 2],
                [4, 5, 6],
                [4, 6, 7],
                [4, 7, 8]
            ]
        );
    }
    std::fs::write(
        dir.join("h.ron"),
        scene_text("(mesh: \"set.usdc\", prim: \"/World/rig/hill\")"),
    )
    .unwrap();
    let loaded = scene::load_scene(&dir.join("h.ron")).unwrap();
    assert!(loaded.surfaces.expect("surfaces").has_holdouts());
}

/// Meshes nephele cannot use: each an error located at the scene's `holdouts[0].prim` (or
/// `.mesh`), naming the USD file.
#[test]
fn usd_holdout_errors_are_located_and_name_the_file() {
    let dir = temp_dir("usd-holdout-errors");
    let mesh = |body: &str| {
        format!(
            "#usda 1.0\n\ndef Xform \"World\"\n{{\n    def Mesh \"m\"\n    {{\n{body}\n    }}\n\n    \
             def Xform \"group\"\n    {{\n    }}\n}}\n"
        )
    };
    let quad =
        "        int[] faceVertexCounts = [4]\n        int[] faceVertexIndices = [0, 1, 2, 3]\n";
    let pts = "        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]\n";
    let cases: Vec<(&str, String, &str, &[&str])> = vec![
        (
            "missing.usda",
            mesh(&format!("{quad}{pts}")),
            "/World/nope",
            &["holdouts[0].prim: ", "no prim at /World/nope", "/World"],
        ),
        (
            "group.usda",
            mesh(&format!("{quad}{pts}")),
            "/World/group",
            &["holdouts[0].prim: ", "/World/group is a Xform, not a Mesh"],
        ),
        (
            "nopoints.usda",
            mesh(quad),
            "/World/m",
            &["holdouts[0].prim: ", "/World/m has no points"],
        ),
        (
            "range.usda",
            mesh(&format!(
                "        int[] faceVertexCounts = [4]\n        int[] faceVertexIndices = [0, 1, 2, 4]\n{pts}"
            )),
            "/World/m",
            &[
                "holdouts[0].prim: ",
                "/World/m.faceVertexIndices[3] is 4, out of range for its 4 points",
            ],
        ),
        (
            "face.usda",
            mesh(&format!(
                "        int[] faceVertexCounts = [2, 2]\n        int[] faceVertexIndices = [0, 1, 2, 3]\n{pts}"
            )),
            "/World/m",
            &[
                "holdouts[0].prim: ",
                "/World/m.faceVertexCounts[0] is 2; a face needs at least 3 vertices",
            ],
        ),
        (
            "inf.usda",
            mesh(&format!(
                "{quad}        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 3e38)]\n        \
                 double3 xformOp:scale = (1, 1, 1e300)\n        \
                 uniform token[] xformOpOrder = [\"xformOp:scale\"]\n"
            )),
            "/World/m",
            &["holdouts[0].prim: ", "/World/m.points[3]", "must be finite"],
        ),
    ];
    for (file, usda, prim, wants) in cases {
        std::fs::write(dir.join(file), usda).unwrap();
        let bad = dir.join("bad.ron");
        std::fs::write(
            &bad,
            scene_text(&format!("(mesh: \"{file}\", prim: \"{prim}\")")),
        )
        .unwrap();
        let e = scene::load_scene(&bad).unwrap_err().to_string();
        // `  holdouts: [(mesh: "F", prim: "` — the prim's value starts after it.
        let column = format!("  holdouts: [(mesh: \"{file}\", prim: ")
            .chars()
            .count()
            + 1;
        let at = format!("bad.ron:3:{column}: ");
        for w in wants.iter().chain([&at.as_str(), &file]) {
            assert!(e.contains(w), "{w:?} not in {e}");
        }
        eprintln!("{e}");
    }
    // Errors at `mesh`: a stage without a visible mesh, `prim` on an OBJ, a file not USD.
    std::fs::write(
        dir.join("empty.usda"),
        "#usda 1.0\n\ndef Xform \"World\"\n{\n}\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("garbage.usda"),
        "#usda 1.0\n\ndef Mesh \"m\" {{{\n",
    )
    .unwrap();
    std::fs::write(dir.join("w.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    for (holdout, wants) in [
        (
            "(mesh: \"empty.usda\")",
            &[
                "bad.ron:3:21: holdouts[0].mesh: ",
                "empty.usda: the stage has no visible Mesh prim",
            ][..],
        ),
        (
            "(mesh: \"garbage.usda\")",
            &["bad.ron:3:21: holdouts[0].mesh: ", "garbage.usda: "][..],
        ),
        (
            "(mesh: \"w.obj\", prim: \"/m\")",
            &[
                "bad.ron:3:36: holdouts[0].prim: ",
                "w.obj: `prim` names a prim of a USD stage",
            ][..],
        ),
    ] {
        let bad = dir.join("bad.ron");
        std::fs::write(&bad, scene_text(holdout)).unwrap();
        let e = scene::load_scene(&bad).unwrap_err().to_string();
        for w in wants {
            assert!(e.contains(w), "{w:?} not in {e}");
        }
        eprintln!("{e}");
    }
    // A hidden mesh is not read by default; named, it is.
    std::fs::write(
        dir.join("hidden.usda"),
        mesh(&format!(
            "{quad}{pts}        token visibility = \"invisible\"\n"
        )),
    )
    .unwrap();
    assert!(usd_mesh::read(&dir.join("hidden.usda"), None).is_err());
    assert_eq!(
        usd_mesh::read(&dir.join("hidden.usda"), Some("/World/m"))
            .unwrap()
            .triangles
            .len(),
        2
    );
    // A holdout's render is not run: no output for an error.
    let o = nephele_in(&dir)
        .args(["render", "bad.ron", "--output", "bad-out"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(!dir.join("bad-out").exists());
}
