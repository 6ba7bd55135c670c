//! Tests of the job files: hostile values quoted or refused, scripts parsed by bash.
use super::value::sbatch_quote;
use super::*;
use std::path::Path;
use std::process::Command;

fn job() -> FarmJob {
    FarmJob {
        name: "duck-diffusion-preview".into(),
        nephele: "/opt/nephele/bin/nephele".into(),
        scene: "/farm/scenes/duck diffusion.ron".into(),
        output: "/farm/renders/duck".into(),
        frames: (1..=96).collect(),
        tasks: 4,
        preview: true,
        overrides: Vec::new(),
        logs: "/farm/renders/duck/preview/logs".into(),
        origins: Origins::default(),
    }
}

/// `job()` with every path under the folder `hostile`.
fn hostile_job(hostile: &str) -> FarmJob {
    let out = PathBuf::from("/farm").join(hostile);
    FarmJob {
        nephele: out.join("bin/nephele"),
        scene: out.join("shot.ron"),
        logs: out.join("preview/logs"),
        output: out,
        ..job()
    }
}

/// Both Slurm scripts of `job`, which must be accepted.
fn slurm_scripts(job: &FarmJob) -> [String; 2] {
    [
        slurm_prepare_script(job, &[]).unwrap(),
        slurm_array_script(job, &[]).unwrap(),
    ]
}

/// The words bash makes of `script`'s `exec` line, with `SLURM_ARRAY_TASK_ID=2` (run with
/// `printf` in place of `exec`, in an empty environment, so nothing in it can run).
fn exec_words(script: &str) -> Vec<String> {
    let line = script.lines().find(|l| l.starts_with("exec ")).unwrap();
    let line = format!("printf '%s\\0' {}", &line["exec ".len()..]);
    let out = Command::new("bash")
        .args(["-c", &line])
        .env_clear()
        .env("SLURM_ARRAY_TASK_ID", "2")
        .current_dir(std::env::temp_dir())
        .output()
        .unwrap();
    assert!(out.status.success(), "{line}");
    let text = String::from_utf8(out.stdout).unwrap();
    text.split_terminator('\0').map(str::to_string).collect()
}

/// Whether `bash -n` parses `script`.
fn bash_parses(script: &str) -> bool {
    use std::io::Write;
    let mut child = Command::new("bash")
        .arg("-n")
        .stdin(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(script.as_bytes())
        .unwrap();
    child.wait().unwrap().success()
}

/// The arguments sbatch makes of an `#SBATCH` line's rest, as Slurm 22.05's `sbatch/opt.c`
/// (`_get_argument`) reads them: whitespace splits, `'` and `"` quote, `\` escapes, an
/// unquoted `#` ends the line.
fn sbatch_words(line: &str) -> Vec<String> {
    let (mut words, mut word, mut quote) = (Vec::new(), None::<String>, None);
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match (quote, c) {
            (_, '\\') => {
                let next = chars.next().expect("sbatch would fail on a final \\");
                word.get_or_insert_default().push(next);
            }
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.get_or_insert_default().push(c),
            (None, '"' | '\'') => {
                quote = Some(c);
                word.get_or_insert_default();
            }
            (None, '#') => break,
            (None, c) if c.is_whitespace() => words.extend(word.take()),
            (None, c) => word.get_or_insert_default().push(c),
        }
    }
    assert!(quote.is_none(), "sbatch would fail on {line:?}");
    words.extend(word);
    words
}

/// The value of the `#SBATCH --output=` option of `script`, as sbatch reads it.
fn sbatch_output_option(script: &str) -> String {
    let words: Vec<String> = script
        .lines()
        .filter_map(|l| l.strip_prefix("#SBATCH"))
        .flat_map(sbatch_words)
        .collect();
    let outputs: Vec<&String> = words
        .iter()
        .filter(|w| w.starts_with("--output="))
        .collect();
    assert_eq!(outputs.len(), 1, "{script}");
    outputs[0]["--output=".len()..].to_string()
}

#[test]
fn array_script_runs_one_chunk_per_task() {
    let s = slurm_array_script(&job(), &["--partition=render".into()]).unwrap();
    assert!(s.starts_with("#!/bin/bash\n"));
    for line in [
        "#SBATCH --array=0-3\n",
        "#SBATCH --requeue\n",
        "#SBATCH --partition=render\n",
        "#SBATCH --output=/farm/renders/duck/preview/logs/duck-diffusion-preview_%A_%a.log\n",
        "exec '/opt/nephele/bin/nephele' 'render' '/farm/scenes/duck diffusion.ron' '--output' \
         '/farm/renders/duck' '--frames' '1..96' '--task' \"${SLURM_ARRAY_TASK_ID}\"'/4' \
         '--preview'\n",
    ] {
        assert!(s.contains(line), "missing {line:?} in\n{s}");
    }
    // sbatch reads #SBATCH lines only before the first command.
    let first_command = s.find("\nset -eu").unwrap();
    assert!(s.rfind("#SBATCH").unwrap() < first_command);
    assert_eq!(exec_words(&s)[8], "2/4");
}

#[test]
fn prepare_script_fits_once() {
    let s = slurm_prepare_script(&job(), &[]).unwrap();
    assert!(s.contains("#SBATCH --job-name=duck-diffusion-preview-prepare\n"));
    assert!(s.contains(
        "exec '/opt/nephele/bin/nephele' 'prepare' '/farm/scenes/duck diffusion.ron' '--output' '/farm/renders/duck' '--preview'\n"
    ));
}

#[test]
fn indexed_job_reads_the_completion_index() {
    let pod = K8sPod {
        image: "registry/nephele:0.1".into(),
        volume_claim: "renders".into(),
        mount: k8s_mount(&job()).unwrap(),
    };
    let s = k8s_indexed_job(&job(), &pod).unwrap();
    assert!(s.contains("completionMode: Indexed\n  completions: 4\n"));
    assert!(s.contains("\"--task\", \"auto/4\""));
    assert!(s.contains("mountPath: \"/farm\"\n"));
    assert!(s.contains("claimName: \"renders\"\n"));
    let prepare = k8s_prepare_job(&job(), &pod).unwrap();
    assert!(prepare.contains("name: duck-diffusion-preview-prepare\n"));
    // A name YAML would read as a number or a boolean is quoted.
    let yes = FarmJob {
        name: "yes".into(),
        ..job()
    };
    assert!(
        k8s_indexed_job(&yes, &pod)
            .unwrap()
            .contains("name: \"yes\"\n")
    );
    assert_eq!(
        write_value(&Value::own("123"), Place::YamlName).unwrap(),
        "\"123\""
    );
    let apart = FarmJob {
        output: "/tmp/out".into(),
        ..job()
    };
    assert_eq!(k8s_mount(&apart), None);
}

#[test]
fn sbatch_options_cannot_inject_lines() {
    let bad = ["--comment=x\necho INJECTED".to_string()];
    let e = check_sbatch_args(&bad).unwrap_err().to_string();
    assert!(e.contains("control character '\\n'"), "{e}");
    assert!(e.contains("(from --sbatch-arg)"), "{e}");
    assert!(slurm_array_script(&job(), &bad).is_err());
    assert!(slurm_prepare_script(&job(), &bad).is_err());
    assert!(check_sbatch_args(&["--comment=\"x\"".into()]).is_err());
    assert!(check_sbatch_args(&["echo".into()]).is_err());
    let spaced = ["--comment=two words".to_string()];
    assert!(check_sbatch_args(&spaced).is_ok());
    let s = slurm_array_script(&job(), &spaced).unwrap();
    assert!(s.contains("#SBATCH \"--comment=two words\"\n"), "{s}");
    // A lone `'` would open a quote sbatch never closes; `\` is an escape there.
    let odd = ["--comment=it's".to_string(), r"--comment=a\b".to_string()];
    let s = slurm_array_script(&job(), &odd).unwrap();
    assert!(s.contains("#SBATCH \"--comment=it's\"\n"), "{s}");
    assert!(s.contains("#SBATCH \"--comment=a\\\\b\"\n"), "{s}");
    let read: Vec<String> = s
        .lines()
        .filter_map(|l| l.strip_prefix("#SBATCH"))
        .flat_map(sbatch_words)
        .filter(|w| w.starts_with("--comment"))
        .collect();
    assert_eq!(read, odd);
    let named = FarmJob {
        name: "my shot; rm -rf".into(),
        ..job()
    };
    let s = slurm_array_script(&named, &[]).unwrap();
    assert!(s.contains("#SBATCH --job-name=my_shot__rm_-rf\n"), "{s}");
}

#[test]
fn hostile_folders_are_quoted_word_for_word() {
    for hostile in [
        "renders %j %A_%a 100%",
        "it's",
        "$(touch X)",
        "`touch X`",
        "two  spaces",
        "a;b&c|d>e<f",
        "shot #2",
        "$HOME ${PATH} *?[x]",
        "~user",
        "é ☁",
    ] {
        let job = hostile_job(hostile);
        for s in slurm_scripts(&job) {
            assert!(bash_parses(&s), "bash -n fails on {hostile:?}:\n{s}");
            let words = exec_words(&s);
            assert_eq!(Path::new(&words[0]), job.nephele, "{s}");
            assert_eq!(Path::new(&words[2]), job.scene, "{s}");
            assert_eq!(Path::new(&words[4]), job.output, "{s}");
            // The #SBATCH block is whole: comments up to the first blank line.
            let block: Vec<&str> = s.lines().skip(1).take_while(|l| !l.is_empty()).collect();
            assert!(block.iter().all(|l| l.starts_with('#')), "{s}");
            let logs = job.logs.to_str().unwrap().replace('%', "%%");
            assert!(
                sbatch_output_option(&s).starts_with(&format!("{logs}/duck-diffusion-preview")),
                "{s}"
            );
        }
        let array = slurm_array_script(&job, &[]).unwrap();
        assert!(
            array.contains("#SBATCH --array=0-3\n#SBATCH --requeue\n"),
            "{array}"
        );
        assert!(sbatch_output_option(&array).ends_with("/duck-diffusion-preview_%A_%a.log"));
        let words = exec_words(&array);
        assert_eq!(words[8], "2/4");
    }
}

#[test]
fn line_breaks_are_refused_wherever_they_come_from() {
    for bad in [
        "a\nb",
        "a\rb",
        "a\tb",
        "a\0b",
        "a\u{7f}b",
        "a\u{85}b",
        "a\u{2028}b",
    ] {
        let pod = K8sPod {
            image: "nephele".into(),
            volume_claim: "claim".into(),
            mount: "/farm".into(),
        };
        let cases: [(FarmJob, &str); 4] = [
            (
                FarmJob {
                    output: format!("/farm/{bad}").into(),
                    ..job()
                },
                "the output folder",
            ),
            (
                FarmJob {
                    logs: format!("/farm/{bad}/logs").into(),
                    ..job()
                },
                "the logs folder",
            ),
            (
                FarmJob {
                    scene: format!("/farm/{bad}.ron").into(),
                    ..job()
                },
                "the scene file",
            ),
            (
                FarmJob {
                    nephele: format!("/farm/{bad}").into(),
                    ..job()
                },
                "the nephele program",
            ),
        ];
        for (job, what) in cases {
            let mut errors = vec![
                slurm_prepare_script(&job, &[]).unwrap_err(),
                slurm_array_script(&job, &[]).unwrap_err(),
            ];
            // The logs folder is only in the Slurm scripts.
            if what != "the logs folder" {
                errors.push(k8s_prepare_job(&job, &pod).unwrap_err());
                errors.push(k8s_indexed_job(&job, &pod).unwrap_err());
            }
            for e in errors {
                assert_eq!(e.what, what);
                let text = e.to_string();
                assert!(text.contains("control character"), "{text}");
                assert!(text.contains(&format!("{bad:?}")[1..4]), "{text}");
                assert!(text.contains("(from "), "{text}");
                assert!(
                    text.contains("rename") || text.contains("install"),
                    "{text}"
                );
            }
        }
    }
}

#[test]
fn what_sbatch_cannot_read_is_refused_only_there() {
    let pod = K8sPod {
        image: "nephele".into(),
        volume_claim: "claim".into(),
        mount: "/farm".into(),
    };
    for bad in ["say \"hi\"", r"back\slash"] {
        let job = hostile_job(bad);
        let e = slurm_array_script(&job, &[]).unwrap_err();
        assert_eq!(e.what, "the logs folder", "{e}");
        assert!(e.to_string().contains("#SBATCH"), "{e}");
        assert!(slurm_prepare_script(&job, &[]).is_err());
        // A Kubernetes manifest holds any text in a JSON-escaped string.
        let s = k8s_indexed_job(&job, &pod).unwrap();
        let output = serde_json::to_string(job.output.to_str().unwrap()).unwrap();
        assert!(s.contains(&format!("\"--output\", {output}")), "{s}");
    }
    // The program and the scene are only shell words: any printable text is fine there.
    let job = FarmJob {
        nephele: "/opt/a\"b\\c/nephele".into(),
        scene: "/farm/\"quoted\" \\.ron".into(),
        ..job()
    };
    for s in slurm_scripts(&job) {
        let words = exec_words(&s);
        assert_eq!(Path::new(&words[0]), job.nephele);
        assert_eq!(Path::new(&words[2]), job.scene);
    }
}

#[cfg(unix)]
#[test]
fn a_path_that_is_not_utf8_is_refused() {
    use std::os::unix::ffi::OsStrExt;
    let job = FarmJob {
        output: Path::new(std::ffi::OsStr::from_bytes(b"/farm/\xff")).to_path_buf(),
        ..job()
    };
    let e = slurm_prepare_script(&job, &[]).unwrap_err();
    assert!(e.to_string().contains("not valid UTF-8"), "{e}");
}

#[test]
fn the_comment_line_is_checked_too() {
    // The comment line is the first place the scene path is written: a line break there
    // would end the comment in the scripts and in the YAML manifests alike.
    let job = FarmJob {
        scene: "/farm/a\n#SBATCH --wrap=x\n.ron".into(),
        ..job()
    };
    for e in [
        slurm_array_script(&job, &[]).unwrap_err(),
        write_value(&job.scene_value(), Place::Comment).unwrap_err(),
    ] {
        assert_eq!(e.what, "the scene file", "{e}");
    }
    let fine = slurm_array_script(&hostile_job("x # y"), &[]).unwrap();
    assert!(
        fine.lines()
            .nth(1)
            .unwrap()
            .starts_with("# Written by `nephele farm`"),
        "{fine}"
    );
}

#[test]
fn quoting_survives_quotes() {
    assert_eq!(shell_quote("it's"), r"'it'\''s'");
    assert_eq!(k8s_name("Duck_Diffusion.v2"), "duck-diffusion-v2");
    // One function names both jobs: `shot_` is `shot` and `shot-prepare`, and a long name
    // keeps its prepare job within Kubernetes' 63 characters.
    let names = k8s_job_names("shot_");
    assert_eq!(
        (names.render.as_str(), names.prepare.as_str()),
        ("shot", "shot-prepare")
    );
    let long = k8s_job_names(&"a".repeat(60));
    assert_eq!(long.render.len(), 55);
    assert_eq!(long.prepare, format!("{}-prepare", long.render));
    assert!(long.prepare.len() <= 63);
    let pattern = |s: &str| sbatch_quote(s, true);
    assert_eq!(pattern("/a b/c").unwrap(), "\"/a b/c\"");
    assert_eq!(pattern("/a/c").unwrap(), "/a/c");
    assert_eq!(pattern("/a/%j").unwrap(), "/a/%%j");
    assert_eq!(pattern("/it's #1").unwrap(), "\"/it's #1\"");
    assert!(pattern("/a\\b").is_err());
    assert!(sbatch_quote("\"", false).is_err());
}

#[test]
fn overrides_reach_every_task_word_for_word() {
    let overrides = vec![
        "shot.width=320".to_string(),
        "camera=Fixed((position: (0.0, 0.5, 3.0), look_at: (0.0, 0.0, 0.0)))".to_string(),
        "output.dir=\"it's $(touch X) `x`\"".to_string(),
    ];
    let with_sets = FarmJob {
        overrides: overrides.clone(),
        ..job()
    };
    for s in slurm_scripts(&with_sets) {
        assert!(bash_parses(&s), "{s}");
        let words = exec_words(&s);
        let sets: Vec<&str> = words
            .windows(2)
            .filter(|w| w[0] == "--set")
            .map(|w| w[1].as_str())
            .collect();
        assert_eq!(sets, overrides, "{s}");
    }
    // A line break cannot be carried into a job file: refused, naming the override.
    let broken = FarmJob {
        overrides: vec!["shot.width=3\n20".to_string()],
        ..job()
    };
    let e = slurm_array_script(&broken, &[]).unwrap_err().to_string();
    assert!(e.contains("--set"), "{e}");
}
