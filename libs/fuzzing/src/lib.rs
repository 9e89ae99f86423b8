//! What robotd's fuzz tests share (a dev-dependency only).
//!
//! Every edge that reads the outside world has a proptest fuzz test; CI runs each for a bounded
//! number of cases, and a developer runs more with `PROPTEST_CASES=20000`. Tests written with
//! the `proptest!` macro need only [`cases`]. Tests that drive a [`TestRunner`] themselves
//! (several properties sharing one expensive setup, such as a served robotd or a
//! pseudo-terminal) use [`runner_config!`] and [`fuzz`]: `TestRunner::new` knows no source file
//! (only the macro sets one), and without one proptest neither saves a failing case nor
//! replays it, so the config names the file.
//!
//! ```
//! use proptest::prelude::*;
//!
//! let config = robotd_fuzzing::runner_config!(robotd_fuzzing::cases(50));
//! robotd_fuzzing::fuzz(config, any::<u8>(), |byte| {
//!     prop_assert!(u16::from(byte) < 256);
//!     Ok(())
//! });
//! ```

use proptest::strategy::Strategy;
use proptest::test_runner::{
    Config as ProptestConfig, FileFailurePersistence, TestCaseResult, TestRunner,
};

/// `PROPTEST_CASES` when set (a longer run), else `default` (the bounded CI run).
pub fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// A config for `cases` cases whose failures are saved to, and replayed first from,
/// `<test>.proptest-regressions` next to `source_file` (use [`runner_config!`], which passes
/// the caller's `file!()`). `PROPTEST_DISABLE_FAILURE_PERSISTENCE` still turns that off.
/// Shrinking stops after a minute (a hanging case costs a timeout per shrink step).
pub fn config_for(source_file: &'static str, cases: u32) -> ProptestConfig {
    let mut config = ProptestConfig::with_cases(cases);
    config.source_file = Some(source_file);
    if config.failure_persistence.is_some() {
        config.failure_persistence = Some(Box::new(FileFailurePersistence::WithSource(
            "proptest-regressions",
        )));
    }
    config.max_shrink_time = 60_000;
    config
}

/// [`config_for`] the file that calls it.
#[macro_export]
macro_rules! runner_config {
    ($cases:expr) => {
        $crate::config_for(file!(), $cases)
    };
}

/// Runs `test` on `strategy` with a fresh runner (a runner counts its successes across runs,
/// so a second run on the same one would generate no case at all); panics with the failing
/// case, shrunk.
pub fn fuzz<S: Strategy>(
    config: ProptestConfig,
    strategy: S,
    test: impl Fn(S::Value) -> TestCaseResult,
) where
    S::Value: std::fmt::Debug,
{
    let mut runner = TestRunner::new(config);
    if let Err(error) = runner.run(&strategy, test) {
        panic!("{error}\n{runner}");
    }
}
