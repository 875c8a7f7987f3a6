//! The command line explains itself: examples in the help, a single frame as `--frames N`,
//! warnings kept under `--quiet`, and an `info` report in words.

mod common;

use common::{data, scratch};
use std::process::{Command, Output};

fn stereotrace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn help_has_examples_and_every_argument_a_description() {
    let o = stereotrace(&["--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    assert!(
        help.contains("Examples:") && help.contains("stereotrace new"),
        "{help}"
    );
    for command in ["render", "check", "compare", "info", "new"] {
        let o = stereotrace(&[command, "--help"]);
        let help = String::from_utf8_lossy(&o.stdout).to_string();
        let args = help
            .split("Arguments:")
            .nth(1)
            .and_then(|a| a.split("Options:").next())
            .unwrap_or_else(|| panic!("{command}: {help}"));
        // "<A>  what it is", or in clap's long layout the description on the next line.
        let lines: Vec<&str> = args.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if !line.trim_start().starts_with('<') {
                continue;
            }
            let inline = line.trim().split_once("  ").is_some();
            let below = lines.get(i + 1).is_some_and(|l| {
                let t = l.trim_start();
                !t.is_empty() && !t.starts_with('<') && l.len() - t.len() > 4
            });
            assert!(
                inline || below,
                "{command}: an argument without a description: {line}"
            );
        }
    }
}

#[test]
fn one_frame_quietly_with_its_warnings() {
    let dir = scratch("cli-one-frame");
    let p = dir.join("p.toml");
    std::fs::write(
        &p,
        format!(
            "[scene]\npath = {:?}\n[render]\nwidth = 32\nheight = 24\nspp = 1\n[frames]\nend = 10\n\
             [[output]]\nkind = \"png\"\npath = \"f_{{frame:04}}_{{eye}}.png\"\n",
            data()
                .join("scenes/BoxAnimated/BoxAnimated.glb")
                .to_string_lossy()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let o = stereotrace(&[
        "render",
        "--quiet",
        "--frames",
        "7",
        "--out",
        &out.to_string_lossy(),
        &p.to_string_lossy(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning:") && stderr.contains("no lights"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("rendered"),
        "no summary under --quiet: {stderr}"
    );
    let mut pngs: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png"))
        .collect();
    pngs.sort();
    assert_eq!(pngs, ["f_0007_left.png", "f_0007_right.png"]);
}

#[test]
fn info_says_what_a_scene_holds_in_words() {
    let scene = data().join("scenes/InterpolationTest/InterpolationTest.glb");
    let o = stereotrace(&["info", &scene.to_string_lossy()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(text.contains("3: \"Step Rotation\""), "{text}");
    assert!(text.contains("channels: 1 rotation; step"), "{text}");
    assert!(
        text.contains("cameras     none (a render frames the scene"),
        "{text}"
    );
}

#[test]
fn a_closed_pipe_ends_quietly_and_a_full_disk_is_an_error() {
    let scene = data().join("scenes/CesiumMan/CesiumMan.glb");
    // Standard output whose reader is gone: every write fails with a broken pipe.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
        .args(["info", &scene.to_string_lossy()])
        .stdout(writer)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
    // A disk that is full (Linux's /dev/full).
    {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_stereotrace"))
            .args(["info", &scene.to_string_lossy()])
            .stdout(full)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("cannot write to standard output") && !stderr.contains("panicked"),
            "{stderr}"
        );
    }
}

/// Every command a user can type, from `--help`'s list (help itself aside).
fn commands() -> Vec<String> {
    let help = String::from_utf8_lossy(&stereotrace(&["--help"]).stdout).to_string();
    let list = help
        .split("Commands:")
        .nth(1)
        .and_then(|rest| rest.split("\n\n").next())
        .expect("--help lists the commands")
        .to_string();
    let names: Vec<String> = list
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .filter(|n| n != "help")
        .collect();
    assert!(names.len() >= 8, "{names:?}");
    names
}

/// Completion scripts for bash, zsh and fish name every command; bash's parses (`bash -n`).
#[test]
fn completions_for_bash_zsh_and_fish_name_every_command() {
    let commands = commands();
    for shell in ["bash", "zsh", "fish"] {
        let o = stereotrace(&["completions", shell]);
        assert!(o.status.success(), "{shell}");
        let script = String::from_utf8_lossy(&o.stdout);
        for c in &commands {
            assert!(script.contains(c.as_str()), "{shell}: {c} missing");
        }
        if shell == "bash" {
            let dir = scratch("completions");
            let file = dir.join("stereotrace.bash");
            std::fs::write(&file, &o.stdout).unwrap();
            let check = Command::new("bash").arg("-n").arg(&file).output().unwrap();
            assert!(
                check.status.success(),
                "{}",
                String::from_utf8_lossy(&check.stderr)
            );
        }
    }
    assert_eq!(stereotrace(&["completions", "tcsh"]).status.code(), Some(2));
}

/// `man` writes a page for the tool and each command, with the arguments `--help` shows.
#[test]
fn man_pages_cover_the_tool_and_every_command() {
    let dir = scratch("man");
    let o = stereotrace(&["man", "--out", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for c in std::iter::once("stereotrace".to_string())
        .chain(commands().iter().map(|c| format!("stereotrace-{c}")))
    {
        let page = std::fs::read_to_string(dir.join(format!("{c}.1")))
            .unwrap_or_else(|e| panic!("{c}.1: {e}"));
        assert!(
            page.contains(".TH") && page.contains(".SH SYNOPSIS"),
            "{c}.1"
        );
    }
    let render = std::fs::read_to_string(dir.join("stereotrace-render.1")).unwrap();
    assert!(render.contains("\\-\\-shard"), "{render}");
    assert!(dir.join("stereotrace-bench-accel.1").is_file());
}
