use std::path::Path;

use super::*;
use crate::scene::scene_with_overrides;

const SCENE: &str = r#"// a comment: seed: 9, shot: (width: 5)
Scene(
    target: Fit(mesh: "builtin:sphere", blobs: 20, seed: 5),
    camera: Auto((azimuth_deg: 10.0)),
    shot: (width: 64, height: 36, seconds: 0.25),
    output: (name: "a, b: (c)"),
)"#;

fn sets(args: &[&str]) -> Vec<Override> {
    args.iter().map(|a| Override::set(a).unwrap()).collect()
}

fn applied(args: &[&str]) -> Overridden {
    apply(Path::new("s.ron"), SCENE, &sets(args)).unwrap_or_else(|e| panic!("{args:?}: {e}"))
}

fn parsed(text: &str) -> SceneFile {
    super::super::parse(Path::new("s.ron"), text).unwrap()
}

/// Each override gives the scene the same edit in the file gives.
#[test]
fn an_override_is_the_same_edit_in_the_file() {
    let cases: &[(&[&str], &str, &str)] = &[
        // A written value replaced.
        (&["shot.width=128"], "width: 64", "width: 128"),
        // A field the file leaves to its default, in a parent it writes.
        (&["shot.fps=30"], "seconds: 0.25", "seconds: 0.25, fps: 30"),
        // A parent the file does not write: added with its other fields at their defaults.
        (
            &["cloud.density=30"],
            "seed: 5),",
            "seed: 5), cloud: (density: 30),",
        ),
        // Top-level `seed` is not the target's `seed`.
        (&["seed=7"], "    shot:", "    seed: 7, shot:"),
        // A field inside an enum variant's settings.
        (
            &["camera.fov_deg=20"],
            "azimuth_deg: 10.0",
            "azimuth_deg: 10.0, fov_deg: 20",
        ),
        // A whole value; a string with a comma, a colon and brackets.
        (
            &["output.name=\"x, y: (z)\""],
            "\"a, b: (c)\"",
            "\"x, y: (z)\"",
        ),
        // A later override inside an earlier one's value.
        (
            &[
                "sky=Gradient(zenith: (0.1, 0.2, 0.3), horizon: (0.4, 0.5, 0.6))",
                "sky.zenith=(1.0, 1.0, 1.0)",
            ],
            "seed: 5),",
            "seed: 5), sky: Gradient(zenith: (1, 1, 1), horizon: (0.4, 0.5, 0.6)),",
        ),
        // The last of two wins.
        (
            &["shot.height=10", "shot.height=20"],
            "height: 36",
            "height: 20",
        ),
    ];
    for (args, from, to) in cases {
        assert!(SCENE.contains(from), "{from}");
        let edited = SCENE.replacen(from, to, 1);
        assert_eq!(applied(args).file, parsed(&edited), "{args:?}");
        assert_ne!(applied(args).file, parsed(SCENE), "{args:?}");
    }
}

#[test]
fn values_that_write_more_than_one_field_are_refused() {
    for bad in [
        "shot.width=1), seed: (3",
        "shot.width=1, height: 2",
        "seed=1 // rest",
        "output.name=\"open",
        "shot.width=",
        "shot..width=3",
        "shot.width",
        "9shot=3",
        "frames=(1, 2",
    ] {
        assert!(Override::set(bad).is_err(), "{bad}");
    }
    assert!(Override::set("frames=(1, 2)").is_ok());
    assert!(Override::set("output.name=r#\"a\"b\"#").is_ok());
}

#[test]
fn sizes_parse() {
    let [w, h] = Override::size("1920x1080").unwrap();
    assert_eq!((w.key.as_str(), w.value.as_str()), ("shot.width", "1920"));
    assert_eq!((h.key.as_str(), h.value.as_str()), ("shot.height", "1080"));
    assert_eq!(w.given, "--size 1920x1080");
    for bad in ["1920", "0x10", "10x", "ax3", "10x-3"] {
        assert!(Override::size(bad).is_err(), "{bad}");
    }
}

fn error(args: &[&str]) -> String {
    match scene_with_overrides(Path::new("s.ron"), SCENE, &sets(args)) {
        Ok(_) => panic!("{args:?} loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn errors_name_the_override() {
    assert_eq!(
        error(&["shot.width=abc"]),
        "--set shot.width=abc: shot.width: expected an integer, got abc"
    );
    let e = error(&["shot.widht=3"]);
    assert!(
        e.starts_with("--set shot.widht=3: shot.widht: no field named `widht` in shot; nearest: width (known: width, height,"),
        "{e}"
    );
    let e = error(&["clouds.density=3"]);
    assert!(e.contains("nearest: cloud "), "{e}");
    let e = error(&["camera=Fxed(())"]);
    assert!(e.contains("no variant named `Fxed`; nearest: Fixed"), "{e}");
    // Valid RON, invalid scene: the validation's message, said of the override.
    assert_eq!(
        error(&["shot.width=0"]),
        "--set shot.width=0: shot: width and height must be positive, got 0×36"
    );
    assert_eq!(
        error(&["cloud.density=-1"]),
        error(&["cloud=(density: -1)"]).replace("cloud=(density: -1)", "cloud.density=-1")
    );
    assert!(error(&["shot.width.x=3"]).contains("shot.width is 64, not a group of fields"));
    let e = error(&["holdouts.mesh=\"a\""]);
    assert!(e.contains("holdouts.mesh: expected opening `[`"), "{e}");
}

#[test]
fn the_files_own_errors_keep_their_place() {
    // The file's error is after the text an override adds: still at its own line and column.
    let bad = SCENE.replace("blobs: 20", "blobs: 0");
    let place = |args: &[&str]| {
        scene_with_overrides(Path::new("s.ron"), &bad, &sets(args))
            .unwrap_err()
            .to_string()
    };
    let plain = place(&[]);
    assert!(plain.starts_with("s.ron:3:"), "{plain}");
    assert_eq!(place(&["seed=3", "cloud.density=30"]), plain);
}

#[test]
fn a_file_with_attributes_takes_overrides() {
    let text = format!("#![enable(implicit_some)]\n{SCENE}");
    let o = apply(Path::new("s.ron"), &text, &sets(&["seed=7", "shot.fps=30"])).unwrap();
    let edited = text
        .replacen("    shot:", "    seed: 7, shot:", 1)
        .replacen("seconds: 0.25", "seconds: 0.25, fps: 30", 1);
    assert_eq!(o.file, parsed(&edited));
}
