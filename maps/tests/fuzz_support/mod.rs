//! Shared machinery of the parser fuzz tests (`maps/tests/fuzz.rs`, `tests/fuzz_parsers.rs`).
//!
//! Each parser gets mutations of small valid files of its format (truncation, byte flips,
//! huge / negative counts, `NaN`, `1e999`, duplicated and deleted lines, a very long line,
//! non-UTF-8 bytes) and purely random bytes, from a fixed seed. The property: the parser
//! returns (a value or a typed error) without panicking, within [`time_limit`], and no
//! single allocation made while it runs exceeds what the input's size justifies.
//!
//! `SEGLOC_FUZZ_CASES` (else `PROPTEST_CASES`) sets the cases per parser (default 2,000);
//! `SEGLOC_FUZZ_SEED` (a number) changes the seed. `scripts/fuzz.sh` sets both.
#![allow(dead_code)]

use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The global allocator of the fuzz test binaries: [`System`], noting the largest single
/// request while armed.
pub struct Tracking;

static ARMED: AtomicBool = AtomicBool::new(false);
static LARGEST: AtomicUsize = AtomicUsize::new(0);
/// Requests above this fail (the test binary aborts naming the size) instead of risking
/// the machine; smaller oversized requests succeed and fail the property (so they shrink).
const REFUSE_BYTES: usize = 1 << 30;

impl Tracking {
    fn note(size: usize) -> bool {
        if ARMED.load(Ordering::Relaxed) {
            LARGEST.fetch_max(size, Ordering::Relaxed);
            return size <= REFUSE_BYTES;
        }
        true
    }
}

unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !Self::note(layout.size()) {
            return std::ptr::null_mut();
        }
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !Self::note(layout.size()) {
            return std::ptr::null_mut();
        }
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !Self::note(new_size) {
            return std::ptr::null_mut();
        }
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

/// One fuzz target at a time per test binary: the allocation tracking is global (parsers
/// may allocate on rayon's threads).
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Cases per parser: `SEGLOC_FUZZ_CASES`, else `PROPTEST_CASES`, else 2,000.
pub fn cases() -> u32 {
    ["SEGLOC_FUZZ_CASES", "PROPTEST_CASES"]
        .iter()
        .find_map(|k| std::env::var(k).ok()?.trim().parse().ok())
        .unwrap_or(2000)
}

/// Longest a case may take: well under a second in release, looser unoptimised.
pub fn time_limit() -> Duration {
    if cfg!(debug_assertions) {
        Duration::from_secs(5)
    } else {
        Duration::from_millis(500)
    }
}

/// Largest single allocation an input of `len` bytes justifies for a plain-text parser:
/// a fixed allowance plus a generous multiple of the input.
pub fn text_bound(len: usize) -> usize {
    (256 << 10) + 64 * len
}

/// Tokens spliced into inputs: huge, negative and non-finite numbers and structure.
const TOKENS: &[&str] = &[
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "4294967295",
    "4294967296",
    "1000000000000",
    "99999999999999999999999999",
    "-1",
    "-9223372036854775808",
    "-0",
    "0",
    "NaN",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "1e999",
    "-1e999",
    "1e308",
    "1e-320",
    "0x10",
    "\u{feff}",
    "\"",
    "[",
    "]",
    "(",
    ")",
    "{",
    "}",
    ",",
    ",,,,",
    ":",
    "=",
    "\n",
    "\r\n",
    "\r",
    "#",
    " ",
    "\t",
    "é",
    "\u{10ffff}",
];

/// Byte sequences that are not UTF-8.
const NOT_UTF8: &[&[u8]] = &[
    b"\xff",
    b"\xfe\xff",
    b"\xc3",
    b"\xed\xa0\x80",
    b"\x80\x80",
    b"\0",
];

/// One mutation: (kind, position, extra).
pub type Op = (u8, usize, u32);

fn line_starts(b: &[u8]) -> Vec<usize> {
    let mut v = vec![0];
    v.extend(
        b.iter()
            .enumerate()
            .filter(|(_, &c)| c == b'\n')
            .map(|(k, _)| k + 1),
    );
    v
}

/// The line `[start, end)` (end includes its newline) containing byte `pos`.
fn line_at(b: &[u8], pos: usize) -> (usize, usize) {
    let start = b[..pos]
        .iter()
        .rposition(|&c| c == b'\n')
        .map_or(0, |k| k + 1);
    let end = b[pos..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |k| pos + k + 1);
    (start, end)
}

/// Apply the mutations `ops` to `seed`.
pub fn mutate(seed: &[u8], ops: &[Op]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for &(kind, pos, extra) in ops {
        let at = if b.is_empty() { 0 } else { pos % (b.len() + 1) };
        let token = TOKENS[extra as usize % TOKENS.len()].as_bytes();
        match kind % 11 {
            // truncation at a random boundary
            0 => b.truncate(at),
            // byte flip
            1 if !b.is_empty() => {
                let k = pos % b.len();
                b[k] ^= (extra as u8).max(1);
            }
            // insert a token
            2 => {
                b.splice(at..at, token.iter().copied());
            }
            // replace the number (or word) at a position with a token
            3 | 4 if !b.is_empty() => {
                let k = pos % b.len();
                let word = |c: u8| c.is_ascii_alphanumeric() || b".-+_".contains(&c);
                let start = b[..k].iter().rposition(|&c| !word(c)).map_or(0, |s| s + 1);
                let end = b[k..]
                    .iter()
                    .position(|&c| !word(c))
                    .map_or(b.len(), |e| k + e);
                b.splice(start..end, token.iter().copied());
            }
            // duplicate a line
            5 if !b.is_empty() => {
                let (s, e) = line_at(&b, pos % b.len());
                let line = b[s..e].to_vec();
                b.splice(e..e, line);
            }
            // delete a line
            6 if !b.is_empty() => {
                let (s, e) = line_at(&b, pos % b.len());
                b.drain(s..e);
            }
            // a very long line at a line start
            7 => {
                let starts = line_starts(&b);
                let s = starts[pos % starts.len()];
                let n = 1 + (extra as usize % 200_000);
                let unit: &[u8] = match extra % 4 {
                    0 => b"9",
                    1 => b"1,",
                    2 => b" ",
                    _ => b"(1,2,3), ",
                };
                let mut line: Vec<u8> = unit.iter().copied().cycle().take(n).collect();
                line.push(b'\n');
                b.splice(s..s, line);
            }
            // non-UTF-8 bytes
            8 => {
                let bad = NOT_UTF8[extra as usize % NOT_UTF8.len()];
                b.splice(at..at, bad.iter().copied());
            }
            // swap a line with the first
            9 if !b.is_empty() => {
                let (s, e) = line_at(&b, pos % b.len());
                let line: Vec<u8> = b.drain(s..e).collect();
                b.splice(0..0, line);
            }
            // duplicate a whole region many times (repeated ids / lines)
            10 if !b.is_empty() => {
                let (s, e) = line_at(&b, pos % b.len());
                let line = b[s..e].to_vec();
                let times = 1 + extra as usize % 64;
                for _ in 0..times {
                    b.splice(e..e, line.iter().copied());
                }
            }
            _ => {}
        }
        // compounding long lines and duplications could reach hundreds of MB: a
        // parser linear in its input would then "hang" (and shrinking would never end)
        b.truncate(MAX_INPUT_BYTES);
    }
    b
}

/// Largest mutated input.
pub const MAX_INPUT_BYTES: usize = 1 << 20;

/// Inputs for a parser whose valid files include `seeds`: mostly mutations of a seed, some
/// purely random bytes and random printable text.
pub fn inputs(seeds: Vec<Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    assert!(!seeds.is_empty());
    let n = seeds.len();
    let printable: Vec<u8> = (b' '..=b'~').chain([b'\n', b'\t']).collect();
    prop_oneof![
        1 => proptest::collection::vec(any::<u8>(), 0..600),
        1 => proptest::collection::vec(proptest::sample::select(printable), 0..600),
        8 => (
            0..n,
            proptest::collection::vec((any::<u8>(), any::<usize>(), any::<u32>()), 1..6)
        )
            .prop_map(move |(k, ops)| mutate(&seeds[k], &ops)),
    ]
}

/// A fixed seed per target (its name hashed), changed by `SEGLOC_FUZZ_SEED`.
fn rng_for(name: &str) -> TestRng {
    let salt: u64 = std::env::var("SEGLOC_FUZZ_SEED")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(0x5e6_10c);
    let mut seed = [0u8; 32];
    // FNV-1a of the name, then the salt
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &c in name.as_bytes() {
        h = (h ^ c as u64).wrapping_mul(0x100_0000_01b3);
    }
    seed[..8].copy_from_slice(&h.to_le_bytes());
    seed[8..16].copy_from_slice(&salt.to_le_bytes());
    seed[16..24].copy_from_slice(&h.rotate_left(17).to_le_bytes());
    seed[24..].copy_from_slice(&(!salt).to_le_bytes());
    TestRng::from_seed(RngAlgorithm::ChaCha, &seed)
}

/// Run `parse` over [`cases`] inputs grown from `seeds` (which must all parse) and check
/// the property: no panic, each case within [`time_limit`], no single allocation above
/// `bound(input length)`. `parse` returns the typed error as text (not a failure).
pub fn fuzz(
    name: &str,
    seeds: Vec<Vec<u8>>,
    bound: fn(usize) -> usize,
    parse: impl Fn(&[u8]) -> Result<(), String>,
) {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
    for (k, s) in seeds.iter().enumerate() {
        if let Err(e) = parse(s) {
            panic!("{name}: seed {k} does not parse: {e}");
        }
    }
    let config = Config {
        cases: cases(),
        failure_persistence: None,
        // shrinking stops at the first case that passes; keep it bounded
        max_shrink_iters: 2000,
        ..Config::default()
    };
    let mut runner = TestRunner::new_with_rng(config, rng_for(name));
    let started = Instant::now();
    let counts = std::cell::Cell::new((0usize, 0usize));
    let result = runner.run(&inputs(seeds), |input| {
        LARGEST.store(0, Ordering::Relaxed);
        ARMED.store(true, Ordering::Relaxed);
        let t0 = Instant::now();
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&input)));
        let elapsed = t0.elapsed();
        ARMED.store(false, Ordering::Relaxed);
        let largest = LARGEST.load(Ordering::Relaxed);
        let outcome = match outcome {
            Ok(o) => o,
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                return Err(TestCaseError::fail(format!("panicked: {msg}")));
            }
        };
        let (o, e) = counts.get();
        counts.set(if outcome.is_ok() {
            (o + 1, e)
        } else {
            (o, e + 1)
        });
        prop_assert!(
            elapsed <= time_limit(),
            "took {elapsed:?} on {} bytes",
            input.len()
        );
        let limit = bound(input.len());
        prop_assert!(
            largest <= limit,
            "allocated {largest} bytes at once for {} bytes of input (bound {limit})",
            input.len()
        );
        Ok(())
    });
    let (ok, err) = counts.get();
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    eprintln!(
        "fuzz {name}: {} cases ({ok} parsed, {err} typed errors) in {:.2?}",
        cases(),
        started.elapsed()
    );
}

/// `bytes` as text the way a reader sees it: UTF-8, else with replacement characters (the
/// path readers refuse non-UTF-8 before parsing; this reaches the parser anyway).
pub fn text(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(bytes)
}
