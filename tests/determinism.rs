//! The same pipeline gives bit-identical images whatever the thread count.

mod common;

use common::{repo, scratch};
use stereotrace::pipeline::LoadedPipeline;
use stereotrace::run::{RunOptions, run};

fn render_with(threads: usize) -> Vec<u8> {
    let p = LoadedPipeline::load(&repo().join("pipelines/default.toml")).unwrap();
    let out = scratch(&format!("threads-{threads}"));
    run(
        &p,
        &RunOptions {
            frames: None,
            threads: Some(threads),
            out_dir: out.clone(),
            progress: false,
            shard: None,
            resume: false,
        },
    )
    .unwrap();
    std::fs::read(out.join("out/whitted_0000.exr")).unwrap()
}

#[test]
fn one_and_two_threads_give_bit_identical_exr_files() {
    let a = render_with(1);
    let b = render_with(2);
    assert!(a == b, "EXR bytes differ between 1 and 2 threads");
}
