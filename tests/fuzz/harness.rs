//! The in-test fuzzer: each target's committed corpus (`tests/fuzz/corpus/TARGET/`) replayed, then random
//! mutations of it for a fixed time. Mutations are drawn with proptest (bit flips, byte and 32-bit
//! "interesting" value writes, inserts, deletes, duplicated and spliced ranges); an input whose outcome has
//! not been seen before joins the in-memory corpus, so mutations work their way past checksums and
//! headers into the parsers (outcome-guided, since stable Rust has no coverage instrumentation). A panic is
//! a crash: its input is written to `tests/fuzz/artifacts/TARGET/` (gitignored) and the test fails.

use std::collections::HashSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// One mutation of an input.
#[derive(Clone, Debug)]
enum Mutation {
    FlipBit(prop::sample::Index, u8),
    SetByte(prop::sample::Index, u8),
    /// Writes a value that trips size and sign checks (0, -1, 2^31, ...) as 4 bytes, either endianness.
    SetWord(prop::sample::Index, u32, bool),
    Insert(prop::sample::Index, Vec<u8>),
    Delete(prop::sample::Index, u8),
    /// Copies a range of the input over another place (repeated chunks, doubled headers).
    Duplicate(prop::sample::Index, prop::sample::Index, u8),
    /// Replaces the tail with the tail of another corpus entry (splicing two inputs).
    Splice(prop::sample::Index, prop::sample::Index),
    Truncate(prop::sample::Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let word = prop_oneof![
        Just(0u32),
        Just(1),
        Just(u32::MAX),
        Just(0x7fff_ffff),
        Just(0x8000_0000),
        Just(0xffff),
        Just(0x1_0000),
        any::<u32>()
    ];
    prop_oneof![
        4 => (any::<prop::sample::Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        4 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::SetByte(i, b)),
        2 => (any::<prop::sample::Index>(), word, any::<bool>())
            .prop_map(|(i, w, be)| Mutation::SetWord(i, w, be)),
        2 => (any::<prop::sample::Index>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        2 => (any::<prop::sample::Index>(), 1u8..32).prop_map(|(i, n)| Mutation::Delete(i, n)),
        1 => (any::<prop::sample::Index>(), any::<prop::sample::Index>(), 1u8..64)
            .prop_map(|(a, b, n)| Mutation::Duplicate(a, b, n)),
        1 => (any::<prop::sample::Index>(), any::<prop::sample::Index>())
            .prop_map(|(a, b)| Mutation::Splice(a, b)),
        1 => any::<prop::sample::Index>().prop_map(Mutation::Truncate),
    ]
}

fn apply(input: &mut Vec<u8>, m: &Mutation, other: &[u8], max_len: usize) {
    let len = input.len();
    let at = |i: &prop::sample::Index| if len == 0 { 0 } else { i.index(len) };
    match m {
        Mutation::FlipBit(i, b) if len > 0 => input[at(i)] ^= 1 << b,
        Mutation::SetByte(i, v) if len > 0 => input[at(i)] = *v,
        Mutation::SetWord(i, w, be) if len >= 4 => {
            let p = at(i).min(len - 4);
            let bytes = if *be {
                w.to_be_bytes()
            } else {
                w.to_le_bytes()
            };
            input[p..p + 4].copy_from_slice(&bytes);
        }
        Mutation::Insert(i, bytes) => {
            let p = at(i);
            input.splice(p..p, bytes.iter().copied());
        }
        Mutation::Delete(i, n) if len > 0 => {
            let p = at(i);
            input.drain(p..(p + usize::from(*n)).min(len));
        }
        Mutation::Duplicate(a, b, n) if len > 0 => {
            let (src, dst) = (at(a), at(b));
            let chunk: Vec<u8> = input[src..(src + usize::from(*n)).min(len)].to_vec();
            input.splice(dst..dst, chunk);
        }
        Mutation::Splice(a, b) if !other.is_empty() => {
            input.truncate(at(a));
            input.extend_from_slice(&other[b.index(other.len())..]);
        }
        Mutation::Truncate(i) => input.truncate(at(i)),
        _ => {}
    }
    input.truncate(max_len);
}

/// What one target's run did.
#[derive(Debug, Default)]
pub(crate) struct Report {
    /// Inputs executed (corpus replay included).
    pub(crate) execs: u64,
    /// Inputs that panicked.
    pub(crate) crashes: u64,
    /// Corpus entries at the start.
    pub(crate) corpus: usize,
    /// Outcome-new inputs added.
    pub(crate) added: usize,
    /// Distinct outcomes seen.
    pub(crate) outcomes: usize,
    /// The slowest single input.
    pub(crate) slowest: Duration,
    /// Where the crashing inputs were written.
    pub(crate) artifacts: Vec<PathBuf>,
}

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz")
}

/// The committed corpus of `target`, sorted by name.
pub(crate) fn corpus(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = fuzz_dir().join("corpus").join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("corpus {}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p, bytes)
        })
        .collect()
}

fn run_one(run: fn(&[u8]) -> String, input: &[u8]) -> Result<String, String> {
    catch_unwind(AssertUnwindSafe(|| run(input))).map_err(|p| {
        p.downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| (*s).to_owned()))
            .unwrap_or_else(|| "panic".into())
    })
}

fn save_crash(target: &str, input: &[u8]) -> PathBuf {
    let dir = fuzz_dir().join("artifacts").join(target);
    let _ = std::fs::create_dir_all(&dir);
    let p = dir.join(format!(
        "crash-{}",
        clipsat::hash::hex(clipsat::hash::hash_bytes(input))
    ));
    let _ = std::fs::write(&p, input);
    p
}

/// Replays `target`'s corpus, then mutates it for `budget`; `seed` fixes the mutation sequence. Inputs
/// are capped at `max_len` bytes.
pub(crate) fn fuzz(
    target: &str,
    run: fn(&[u8]) -> String,
    budget: Duration,
    seed: u64,
    max_len: usize,
) -> Report {
    let mut report = Report::default();
    let mut pool: Vec<Vec<u8>> = Vec::new();
    let mut seen = HashSet::new();
    let exec = |input: &[u8], report: &mut Report| -> Option<String> {
        let t = Instant::now();
        let r = run_one(run, input);
        report.slowest = report.slowest.max(t.elapsed());
        report.execs += 1;
        match r {
            Ok(outcome) => Some(outcome),
            Err(msg) => {
                report.crashes += 1;
                let p = save_crash(target, input);
                eprintln!("{target}: CRASH ({msg}), input saved to {}", p.display());
                report.artifacts.push(p);
                None
            }
        }
    };
    for (_, bytes) in corpus(target) {
        if let Some(o) = exec(&bytes, &mut report) {
            seen.insert(o);
        }
        pool.push(bytes);
    }
    report.corpus = pool.len();
    let mut seed_bytes = [0u8; 32];
    seed_bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed_bytes),
    );
    let strategy = (
        any::<prop::sample::Index>(),
        any::<prop::sample::Index>(),
        prop::collection::vec(mutation(), 1..6),
    );
    let end = Instant::now() + budget;
    while Instant::now() < end && !pool.is_empty() {
        let Ok(tree) = strategy.new_tree(&mut runner) else {
            break;
        };
        let (pick, other, mutations) = tree.current();
        let mut input = pool[pick.index(pool.len())].clone();
        let other = &pool[other.index(pool.len())];
        for m in &mutations {
            apply(&mut input, m, other, max_len);
        }
        if let Some(o) = exec(&input, &mut report) {
            // Outcome-new inputs join the pool (bounded, so a long run stays in memory).
            if seen.insert(o) && pool.len() < 4096 {
                pool.push(input);
                report.added += 1;
            }
        }
    }
    report.outcomes = seen.len();
    report
}
