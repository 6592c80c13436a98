//! The fuzz search outside CI (issue 19 point 5): proptest drives the corpus's structure-aware
//! mutators (`tests/fuzz/mod.rs`: which shipped scene or model, which mutations, by seed) for a
//! bounded time, each case run against the real binary under the same timeout, memory cap and
//! verdict as `tests/fuzz_corpus.rs`. Not a coverage-guided fuzzer (`cargo fuzz` needs nightly):
//! a seeded random search whose failures proptest reports with the case's name.
//!
//! ```sh
//! FUZZ_SECS=600 cargo test --release --test fuzz_search -- --ignored --nocapture
//! ```

mod fuzz;
use proptest::prelude::*;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

struct Inputs {
    scenes: Vec<fuzz::SceneBase>,
    models: Vec<fuzz::ModelBase>,
    frame: Vec<u8>,
    root: tempfile::TempDir,
    start: Instant,
    budget: Duration,
}

fn inputs() -> &'static Inputs {
    static INPUTS: OnceLock<Inputs> = OnceLock::new();
    INPUTS.get_or_init(|| {
        let root = tempfile::tempdir().unwrap();
        let frame = fuzz::render_base_frame(root.path());
        let secs = std::env::var("FUZZ_SECS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(300);
        Inputs {
            scenes: fuzz::scene_bases(),
            models: fuzz::model_bases(),
            frame,
            root,
            start: Instant::now(),
            budget: Duration::from_secs(secs),
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100_000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    #[ignore = "a bounded-time search outside CI: FUZZ_SECS=600 cargo test --release --test fuzz_search -- --ignored"]
    fn random_mutations_exit_0_or_2_with_finite_frames(
        class in 0usize..4,
        base in any::<usize>(),
        seed in any::<u64>(),
    ) {
        let inputs = inputs();
        if inputs.start.elapsed() > inputs.budget {
            return Ok(());
        }
        let mut rng = fuzz::Rng::new(seed);
        let index = (seed % 10_000) as usize;
        let case = match class {
            0 | 1 => fuzz::scene_case(index, &inputs.scenes[base % inputs.scenes.len()], &mut rng),
            2 => fuzz::model_case(index, &inputs.models[base % inputs.models.len()], &mut rng),
            _ => fuzz::exr_case(index, &inputs.frame, &mut rng),
        };
        let verdict = fuzz::run_case(&case, inputs.root.path());
        prop_assert!(verdict.is_ok(), "seed {seed}: {}", verdict.unwrap_err());
    }
}
