//! Inputs that ask for more than a machine has: a small file that places one big mesh in a
//! thousand nodes, a huge film, a billion-frame range. Each is refused up front with the
//! estimate and the limit (exit 2), or runs in flat memory, within seconds; never an abort on
//! allocation or the kernel's out-of-memory killer.

mod common;

use base64::Engine;
use common::{bounded, scratch};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn stereotrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stereotrace"))
}

/// A glTF placing one `n` x `n` grid mesh (2 (n-1)^2 triangles) in `copies` nodes, each moved
/// further back.
fn instanced_grid(dir: &Path, n: u32, copies: usize) -> PathBuf {
    let mut bytes = Vec::new();
    for j in 0..n {
        for i in 0..n {
            for v in [i as f32 / n as f32, j as f32 / n as f32, 0.0] {
                bytes.extend(v.to_le_bytes());
            }
        }
    }
    let positions = bytes.len();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            for k in [a, a + 1, a + n, a + 1, a + n + 1, a + n] {
                bytes.extend(k.to_le_bytes());
            }
        }
    }
    let indices = bytes.len() - positions;
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    let g = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": (0..copies).collect::<Vec<_>>()}],
        "nodes": (0..copies).map(|k| json!({"mesh": 0, "translation": [0.0, 0.0, -(k as f32) * 0.01]})).collect::<Vec<_>>(),
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n * n, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5125, "count": indices / 4, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": positions},
            {"buffer": 0, "byteOffset": positions, "byteLength": indices}
        ],
        "buffers": [{"byteLength": bytes.len(), "uri": format!("data:application/octet-stream;base64,{data}")}]
    });
    let p = dir.join("grid.gltf");
    std::fs::write(&p, serde_json::to_string(&g).unwrap()).unwrap();
    p
}

fn pipeline(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(
        &p,
        format!("[scene]\npath = \"grid.gltf\"\n{body}\n[[output]]\nkind = \"png\"\npath = \"f{{frame}}_{{eye}}.png\"\n"),
    )
    .unwrap();
    p
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_mesh_placed_a_thousand_times_is_refused_with_the_estimate() {
    let dir = scratch("resources-instanced");
    let out = dir.join("out");
    // 99,458 triangles placed 1,000 times: 99 million after instancing, from a 1 MB file.
    instanced_grid(&dir, 224, 1000);
    let p = pipeline(&dir, "p.toml", "[render]\nwidth = 32\nheight = 24\nspp = 1");
    for cmd in ["check", "render"] {
        let mut c = stereotrace();
        c.args([cmd, "--max-memory", "16G"]);
        if cmd == "render" {
            c.arg("--out").arg(&out);
        }
        c.arg(&p);
        let o = bounded(c);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {e}");
        for part in [
            "p.toml",
            "99458000 triangles after instancing",
            "over the limit of 16.0 GiB",
            "--max-memory",
        ] {
            assert!(e.contains(part), "{cmd}: expected '{part}' in {e}");
        }
    }
    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
    // `info` counts without placing the copies; `--accel` would build them and is refused.
    let o = bounded({
        let mut c = stereotrace();
        c.args(["info", "--json"]).arg(dir.join("grid.gltf"));
        c
    });
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["triangles"], 99_458_000);
    let o = bounded({
        let mut c = stereotrace();
        c.args(["info", "--accel", "--max-memory", "16G"])
            .arg(dir.join("grid.gltf"));
        c
    });
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("kd-tree of 99458000 triangles"));
    // The same file with ten copies fits, and says what it will need.
    instanced_grid(&dir, 224, 10);
    let o = bounded({
        let mut c = stereotrace();
        c.args(["check", "--max-memory", "16G"]).arg(&p);
        c
    });
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        said.contains("994580 triangles after instancing") && said.contains("MiB of memory"),
        "{said}"
    );
}

#[test]
fn a_film_larger_than_the_limit_is_refused_before_tracing() {
    let dir = scratch("resources-film");
    instanced_grid(&dir, 4, 1);
    let p = pipeline(
        &dir,
        "big.toml",
        "[render]\nwidth = 16384\nheight = 16384\nspp = 4\neye_reuse = \"reproject\"",
    );
    let o = bounded({
        let mut c = stereotrace();
        c.args(["render", "--max-memory", "8G", "--out"])
            .arg(dir.join("out"))
            .arg(&p);
        c
    });
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("film and outputs: ") && e.contains("over the limit of 8.0 GiB"),
        "{e}"
    );
    assert!(!dir.join("out").exists());
    // A limit that is not a size is a usage error.
    let o = bounded({
        let mut c = stereotrace();
        c.args(["check", "--max-memory", "lots"]).arg(&p);
        c
    });
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not a size"));
}

/// Peak resident memory of a running process, from `/proc` (Linux).
fn peak_rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()
}

#[test]
fn a_billion_frame_range_renders_in_flat_memory_and_keeps_its_frame_log() {
    let dir = scratch("resources-frames");
    let out = dir.join("out");
    instanced_grid(&dir, 4, 1);
    let p = pipeline(
        &dir,
        "long.toml",
        "[render]\nwidth = 8\nheight = 6\nspp = 1\n[frames]\nstart = 0\nend = 1000000000",
    );
    let mut child = stereotrace()
        .args(["render", "--quiet", "--out"])
        .arg(&out)
        .arg(&p)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Let it finish a few hundred frames, then measure and stop it as a user would.
    let t0 = Instant::now();
    while !out.join("f300_right.png").exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "frame 300 not reached in 20 s"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "the render ended early"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let peak = peak_rss_kib(child.id());
    assert!(
        Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    // Holding the range as a list took 4 GB before the first frame; 300 MB is generous.
    if let Some(kib) = peak {
        assert!(kib < 300 * 1024, "peak resident memory {kib} KiB");
    }
    // The frame log was written as the frames finished and put in place at the stop.
    let log = std::fs::read_to_string(out.join("frame-log.csv")).unwrap();
    assert!(log.lines().count() > 300, "{} lines", log.lines().count());
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// 100,000 nodes (a 5 MB file): each placing the same triangle a millimetre further along, and
/// a chain 100,000 deep. `info` describes them, and the pile renders: its overlapping copies
/// once made the kd-tree build copy every triangle into every leaf (5,000 copies: 216 s, 8 GB).
#[test]
fn a_hundred_thousand_nodes_load_describe_and_render() {
    let dir = scratch("resources-nodes");
    let triangle: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let data = base64::engine::general_purpose::STANDARD.encode(&triangle);
    let n = 100_000;
    let scene = |nodes: Vec<serde_json::Value>, roots: Vec<usize>| {
        json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": roots}],
            "nodes": nodes,
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": 36, "uri": format!("data:application/octet-stream;base64,{data}")}]
        })
    };
    let pile = scene(
        (0..n)
            .map(|i| json!({"mesh": 0, "translation": [i as f32 * 1e-3, 0.0, 0.0]}))
            .collect(),
        (0..n).collect(),
    );
    let chain = scene(
        (0..n)
            .map(|i| {
                if i + 1 < n {
                    json!({"children": [i + 1]})
                } else {
                    json!({"mesh": 0})
                }
            })
            .collect(),
        vec![0],
    );
    for (name, doc, triangles) in [("pile", pile, n), ("chain", chain, 1)] {
        std::fs::write(dir.join("grid.gltf"), serde_json::to_vec(&doc).unwrap()).unwrap();
        let o = bounded({
            let mut c = stereotrace();
            c.args(["info", "--json"]).arg(dir.join("grid.gltf"));
            c
        });
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(report["nodes"], n, "{name}");
        assert_eq!(report["triangles"], triangles, "{name}");
        let p = pipeline(&dir, "p.toml", "[render]\nwidth = 16\nheight = 12\nspp = 1");
        let o = bounded({
            let mut c = stereotrace();
            c.args(["render", "--quiet", "--out"])
                .arg(dir.join(format!("out-{name}")))
                .arg(&p);
            c
        });
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}
