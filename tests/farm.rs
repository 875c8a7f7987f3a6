//! A render farm's building blocks, through the command line: `--shard I/N` blocks joined by
//! `assemble` give byte-identical files to a single run, `kill -9` at any moment followed by
//! `--resume` ends with identical files and no temporaries, an edit or a torn file makes its
//! frames render again, two workers on one shard corrupt nothing, and `--shard auto` reads the
//! schedulers' variables.

mod common;

use common::{ffmpeg, repo, scratch};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

/// Frames 3..13 (11: divisible by none of 2, 3 and 4) of the animated scene, with every kind
/// of output that needs the whole sequence: videos in both containers, pseudo-stereo (its
/// delayed channel crosses shard edges), a wobble GIF over the range, and per-frame files.
fn pipeline(dir: &Path, background: f32) -> PathBuf {
    let videos = ffmpeg();
    let video = |name: &str| {
        if videos {
            format!("video = \"{name}\"\n")
        } else {
            String::new()
        }
    };
    let text = format!(
        "[scene]\npath = {scene:?}\nanimation = \"all\"\n\
         [render]\nwidth = 64\nheight = 36\nspp = 1\nbackground = [{background}, 0.5, 0.8]\n\
         [stereo]\ninteraxial = 0.1\nconvergence = 4.0\n\
         [frames]\nstart = 3\nend = 13\nfps = 24\n\
         [[output]]\nkind = \"exr\"\npath = \"exr/{{frame}}.exr\"\n\
         [[output]]\nkind = \"png\"\npath = \"png/{{eye}}_{{frame:03}}.png\"\n\
         [[output]]\nkind = \"anaglyph\"\npath = \"ana/{{frame:04}}.png\"\n{ana}\
         [[output]]\nkind = \"side-by-side\"\npath = \"sbs/{{frame:04}}.png\"\n{sbs}\
         [[output]]\nkind = \"pseudo-stereo\"\ndelay = 2\npath = \"pseudo_{{frame:04}}.png\"\n{pseudo}\
         [[output]]\nkind = \"wobble-gif\"\nviews = 3\npath = \"wobble.gif\"\n\
         [[output]]\nkind = \"wobble-gif\"\nper_frame = true\npath = \"wob/{{frame}}.gif\"\n",
        scene = repo().join("scenes/whitted_animated.gltf"),
        ana = video("anaglyph.mp4"),
        sbs = video("sbs.mkv"),
        pseudo = video("pseudo.webm"),
    );
    let p = dir.join(format!("p-{background}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn stereotrace(args: &[&str], pipeline: &Path, out: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_stereotrace"));
    c.args(args)
        .arg(pipeline)
        .arg("--out")
        .arg(out)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX");
    c
}

fn ok(mut c: Command) -> String {
    let o = c.output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{c:?} failed: {text}");
    text
}

/// Every file under `dir` by relative path with its bytes, but the frame log and manifests
/// (they hold timings and which process wrote what).
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let rel = path
                .strip_prefix(dir)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name == "frame-log.csv" || name.starts_with("manifest") {
                continue;
            }
            out.insert(rel, std::fs::read(&path).unwrap());
        }
    }
    out
}

fn assert_same(expected: &BTreeMap<String, Vec<u8>>, got: &Path, what: &str) {
    let got = tree(got);
    let names = |t: &BTreeMap<String, Vec<u8>>| t.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(expected), names(&got), "{what}: the same files");
    for (name, bytes) in expected {
        assert!(got[name] == *bytes, "{what}: {name} differs");
    }
}

/// A single uninterrupted run, the reference of every test here.
fn reference(dir: &Path, pipeline: &Path) -> BTreeMap<String, Vec<u8>> {
    let out = dir.join("single");
    ok(stereotrace(&["render", "--quiet"], pipeline, &out));
    let files = tree(&out);
    assert!(files.contains_key("wobble.gif") && files.contains_key("pseudo_0003.png"));
    if ffmpeg() {
        assert!(files.contains_key("pseudo.webm") && files.contains_key("sbs.mkv"));
    }
    files
}

fn frame_log_frames(out: &Path) -> Vec<u32> {
    let log = std::fs::read_to_string(out.join("frame-log.csv")).unwrap();
    let mut frames: Vec<u32> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    frames.dedup();
    frames
}

#[test]
fn shards_joined_by_assemble_are_byte_identical_to_one_run() {
    let dir = scratch("farm-shards");
    let p = pipeline(&dir, 0.35);
    let single = reference(&dir, &p);
    for n in [1, 2, 3, 4] {
        let out = dir.join(format!("shards-{n}"));
        // Shards in reverse order: nothing may depend on the order they finish in.
        for i in (1..=n).rev() {
            let said = ok(stereotrace(
                &["render", "--shard", &format!("{i}/{n}")],
                &p,
                &out,
            ));
            assert!(said.contains("stereotrace assemble"), "{said}");
            if i == 2 {
                // Not every shard has run: assemble refuses and lists what is missing.
                let o = stereotrace(&["assemble"], &p, &out).output().unwrap();
                let err = String::from_utf8_lossy(&o.stderr);
                assert_eq!(o.status.code(), Some(1), "{err}");
                assert!(err.contains("never finished: 3.."), "{err}");
            }
        }
        assert!(
            !out.join("frame-log.csv").exists(),
            "shards write no frame log"
        );
        ok(stereotrace(&["assemble"], &p, &out));
        assert_same(&single, &out, &format!("{n} shards"));
        assert_eq!(frame_log_frames(&out), (3..=13).collect::<Vec<_>>());
    }
}

#[test]
fn more_shards_than_frames_leave_some_with_nothing_to_do() {
    let dir = scratch("farm-empty-shard");
    let p = pipeline(&dir, 0.35);
    let out = dir.join("out");
    let said = ok(stereotrace(&["render", "--shard", "1/12"], &p, &out));
    assert!(said.contains("shard 1/12 has no frames"), "{said}");
    assert!(!out.exists() || tree(&out).is_empty());
}

/// Starts a render and kills it with SIGKILL after `after`.
fn killed(c: &mut Command, after: Duration) {
    let mut child = c
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(after);
    let _ = child.kill();
    child.wait().unwrap();
}

fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.file_name().unwrap().to_string_lossy().starts_with('.') {
                found.push(path);
            }
        }
    }
    found
}

#[test]
fn killed_at_any_moment_resume_ends_identical_with_no_temporaries() {
    let dir = scratch("farm-kill");
    let p = pipeline(&dir, 0.35);
    let single = reference(&dir, &p);
    // A plain run killed, then resumes killed in turn at other moments (the first ones while
    // the scene loads or the first frame traces, later ones during writes and encodes).
    let out = dir.join("out");
    let delays = [150, 40, 90, 10, 130, 70, 200];
    for (k, ms) in delays.iter().enumerate() {
        let args: &[&str] = if k == 0 {
            &["render"]
        } else {
            &["render", "--resume"]
        };
        killed(&mut stereotrace(args, &p, &out), Duration::from_millis(*ms));
    }
    let said = ok(stereotrace(&["render", "--resume"], &p, &out));
    assert!(said.contains("resume: "), "{said}");
    assert_same(&single, &out, "after kill -9 and --resume");
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new(), "temporaries left");
    assert_eq!(frame_log_frames(&out), (3..=13).collect::<Vec<_>>());

    // Shards killed and resumed in turn, then assembled.
    let out = dir.join("shards");
    for (k, ms) in [60, 120, 30, 90].iter().enumerate() {
        let shard = format!("{}/2", k % 2 + 1);
        killed(
            &mut stereotrace(&["render", "--shard", &shard, "--resume"], &p, &out),
            Duration::from_millis(*ms),
        );
    }
    for shard in ["1/2", "2/2"] {
        ok(stereotrace(
            &["render", "--shard", shard, "--resume"],
            &p,
            &out,
        ));
    }
    ok(stereotrace(&["assemble"], &p, &out));
    assert_same(&single, &out, "shards after kill -9 and --resume");
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new(), "temporaries left");
    let out = dir.join("out");

    // Nothing left to do: nothing is rendered again.
    let said = ok(stereotrace(&["render", "--resume"], &p, &out));
    assert!(
        said.contains("11 of 11 frame(s) finished and unchanged"),
        "{said}"
    );
    assert!(said.contains("rendered no frames"), "{said}");

    // A torn file and a missing one: those frames only, said why.
    let png = out.join("png/left_005.png");
    let bytes = std::fs::read(&png).unwrap();
    std::fs::write(&png, &bytes[..bytes.len() / 2]).unwrap();
    std::fs::remove_file(out.join("exr/9.exr")).unwrap();
    let said = ok(stereotrace(&["render", "--resume"], &p, &out));
    assert!(said.contains("9 of 11 frame(s) finished"), "{said}");
    assert!(
        said.contains("2 frame(s) whose files changed: 5, 9"),
        "{said}"
    );
    assert_same(&single, &out, "after repairing torn frames");
}

#[test]
fn an_edited_pipeline_renders_every_frame_again() {
    let dir = scratch("farm-edit");
    let first = pipeline(&dir, 0.35);
    let out = dir.join("out");
    ok(stereotrace(&["render", "--quiet"], &first, &out));
    let edited = pipeline(&dir, 0.2);
    let said = ok(stereotrace(&["render", "--resume"], &edited, &out));
    assert!(
        said.contains(
            "11 frame(s) made by a different pipeline, scene or build of stereotrace: 3..13"
        ),
        "{said}"
    );
    let expected = reference(&scratch("farm-edit-reference"), &edited);
    assert_same(&expected, &out, "after the edit");
}

#[test]
fn two_workers_on_the_same_shard_corrupt_nothing() {
    let dir = scratch("farm-twice");
    let p = pipeline(&dir, 0.35);
    let single = reference(&dir, &p);
    let out = dir.join("out");
    let twins: Vec<std::process::Child> = (0..2)
        .map(|_| {
            stereotrace(&["render", "--shard", "1/2", "--quiet"], &p, &out)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for t in twins {
        let o: Output = t.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    ok(stereotrace(
        &["render", "--shard", "2/2", "--quiet"],
        &p,
        &out,
    ));
    ok(stereotrace(&["assemble"], &p, &out));
    assert_same(&single, &out, "a shard rendered twice at once");
    assert_eq!(temporaries(&out), Vec::<PathBuf>::new());
}

#[test]
fn shard_auto_reads_slurm_and_kubernetes_variables() {
    let dir = scratch("farm-auto");
    let p = pipeline(&dir, 0.35);
    let frames_done = |out: &Path| -> Vec<u32> {
        let mut frames: Vec<u32> = std::fs::read_dir(out.join("exr"))
            .unwrap()
            .map(|e| {
                let name = e.unwrap().file_name().to_string_lossy().into_owned();
                name.trim_end_matches(".exr").parse().unwrap()
            })
            .collect();
        frames.sort();
        frames
    };
    // Slurm: task 11 of the array 10-12 is shard 2/3 (frames 6..9 of 3..13).
    let out = dir.join("slurm");
    let mut c = stereotrace(&["render", "--shard", "auto", "--quiet"], &p, &out);
    c.env("SLURM_ARRAY_TASK_ID", "11")
        .env("SLURM_ARRAY_TASK_MIN", "10")
        .env("SLURM_ARRAY_TASK_COUNT", "3");
    ok(c);
    assert_eq!(frames_done(&out), [6, 7, 8, 9]);
    assert!(out.join("manifest-shard-2-of-3.jsonl").is_file());
    // Kubernetes: completion index 0 of 4 completions is shard 1/4 (frames 3..4).
    let out = dir.join("k8s");
    let mut c = stereotrace(&["render", "--shard", "auto/4", "--quiet"], &p, &out);
    c.env("JOB_COMPLETION_INDEX", "0");
    ok(c);
    assert_eq!(frames_done(&out), [3, 4]);
    // No scheduler: said clearly, exit 2, nothing written.
    let out = dir.join("none");
    let o = stereotrace(&["render", "--shard", "auto"], &p, &out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no scheduler variables are set"), "{err}");
    assert!(!out.exists());
}

/// A single-node Slurm cluster (`tests/farm/slurm-local.sh`: Debian's slurm-wlm and munge,
/// installed if missing, daemons started without systemd), stopped when dropped. It needs root;
/// without it the test fails, unless `STEREOTRACE_SKIP_SLURM=1` skips it knowingly.
struct SlurmCluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl SlurmCluster {
    fn script() -> PathBuf {
        repo().join("tests/farm/slurm-local.sh")
    }

    fn up(dir: &Path) -> Option<SlurmCluster> {
        let root = Command::new("id")
            .arg("-u")
            .output()
            .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
        if !root {
            common::missing_tool(
                "a local Slurm cluster (it must be started as root)",
                "STEREOTRACE_SKIP_SLURM",
            );
            return None;
        }
        let o = Command::new("bash")
            .arg(Self::script())
            .arg("up")
            .env("SLURM_CI_DIR", dir)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "the Slurm cluster did not start:\n{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        Some(SlurmCluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        })
    }

    fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Submits through `deploy/slurm/submit.sh`; returns the render array's and the assemble
    /// job's ids.
    fn submit(&self, bin: &Path, pipeline: &Path, out: &Path, tasks: u32) -> (String, String) {
        let mut c = self.command(repo().join("deploy/slurm/submit.sh"));
        c.arg(pipeline)
            .arg(out)
            .arg(tasks.to_string())
            .env("STEREOTRACE", bin)
            .env("STEREOTRACE_LOGS", out.with_extension("logs"));
        let said = ok(c);
        let id = |key: &str| {
            said.split_whitespace()
                .find_map(|w| w.strip_prefix(key))
                .unwrap_or_else(|| panic!("no {key} in {said}"))
                .to_string()
        };
        (id("render="), id("assemble="))
    }

    /// Waits until the jobs left the queue; returns each job's (or array task's) final state.
    fn wait(&self, jobs: &[&str]) -> BTreeMap<String, String> {
        let ids = jobs.join(",");
        let t0 = std::time::Instant::now();
        loop {
            let o = self
                .command("squeue")
                .args(["-h", "-j", &ids])
                .output()
                .unwrap();
            if String::from_utf8_lossy(&o.stdout).trim().is_empty() {
                break;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(300),
                "jobs {ids} did not end"
            );
            std::thread::sleep(Duration::from_millis(300));
        }
        let o = self
            .command("squeue")
            .args(["-h", "-t", "all", "-j", &ids, "-o", "%i %T"])
            .output()
            .unwrap();
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(i, s)| (i.to_string(), s.to_string()))
            .collect()
    }
}

impl Drop for SlurmCluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(Self::script())
            .arg("down")
            .env("SLURM_CI_DIR", &self.dir)
            .output();
    }
}

#[test]
fn a_slurm_job_array_then_its_assemble_job_make_what_one_run_makes() {
    let dir = scratch("farm-slurm");
    let Some(cluster) = SlurmCluster::up(&dir.join("cluster")) else {
        return;
    };
    let p = pipeline(&dir, 0.35);
    let single = reference(&dir, &p);
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_stereotrace"));

    let out = dir.join("out");
    let (render, assemble) = cluster.submit(&bin, &p, &out, 3);
    let states = cluster.wait(&[&render, &assemble]);
    assert_eq!(
        states.len(),
        4,
        "three array tasks and the assemble job: {states:?}"
    );
    assert!(states.values().all(|s| s == "COMPLETED"), "{states:?}");
    assert_same(&single, &out, "the Slurm render");
    assert_eq!(frame_log_frames(&out), (3..=13).collect::<Vec<_>>());

    // One task fails: the assemble job never runs (afterok, --kill-on-invalid-dep), nothing
    // of the sequence is written; rerunning the task and assembling repairs it.
    let failing = dir.join("failing-stereotrace");
    std::fs::write(
        &failing,
        format!(
            "#!/bin/sh\nif [ \"${{SLURM_ARRAY_TASK_ID:-}}\" = 1 ]; then echo 'failing on purpose' >&2; exit 3; fi\nexec {:?} \"$@\"\n",
            bin
        ),
    )
    .unwrap();
    Command::new("chmod")
        .arg("+x")
        .arg(&failing)
        .status()
        .unwrap();
    let out = dir.join("out-failed");
    let (render, assemble) = cluster.submit(&failing, &p, &out, 3);
    let states = cluster.wait(&[&render, &assemble]);
    assert_eq!(states[&format!("{render}_1")], "FAILED", "{states:?}");
    assert_ne!(
        states.get(&assemble).map(String::as_str),
        Some("COMPLETED"),
        "{states:?}"
    );
    assert!(!out.join("wobble.gif").exists() && !out.join("frame-log.csv").exists());
    ok(stereotrace(
        &["render", "--shard", "2/3", "--resume"],
        &p,
        &out,
    ));
    ok(stereotrace(&["assemble"], &p, &out));
    assert_same(
        &single,
        &out,
        "the Slurm render after its failed task was rerun",
    );
}
