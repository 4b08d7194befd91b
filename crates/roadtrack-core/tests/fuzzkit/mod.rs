//! Shared kit of the fuzz tests (issue 15, part 5): bounded, seeded fuzzing on stable Rust
//! inside `cargo test`, with proptest.
//!
//! A case is either a valid seed file changed by a few structured mutations (a field set to
//! NaN, ±inf, a huge, negative or empty value, a column cut, a row duplicated, an extra
//! column, a BOM, CRLF line ends, truncation at a byte, bytes inserted or overwritten) or
//! raw random bytes. [`run`] drives `cases` cases from a fixed seed (derived from the test's
//! name), writes no failure-persistence files, and turns a panic of the check into a test
//! failure that prints the exact input bytes, ready to paste into a regression test.
//!
//! Other crates include this file with `#[path = "../../roadtrack-core/tests/fuzzkit/mod.rs"]`.
// Choice: a file shared by `#[path]` rather than a published test-support crate or module:
// it needs proptest, which must stay a dev-dependency of every crate.
#![allow(dead_code)]

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use std::panic::{AssertUnwindSafe, catch_unwind};

/// How many times more cases the `#[ignore]`d deep runs use.
pub const DEEP: u32 = 100;

/// The syntax of the file being mutated: what separates fields and how values are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Syntax {
    /// Comma-separated values (detections, MOTChallenge, trajectories, …).
    Csv,
    /// `key=value` lines (`seqinfo.ini`).
    Ini,
    /// TOML (`key = value` lines): values are written as TOML literals.
    Toml,
}

impl Syntax {
    fn separator(self) -> u8 {
        match self {
            Syntax::Csv => b',',
            Syntax::Ini | Syntax::Toml => b'=',
        }
    }
}

/// A replacement value for one field.
#[derive(Debug, Clone)]
pub enum Value {
    /// Not a number.
    Nan,
    /// +∞.
    Inf,
    /// −∞.
    NegInf,
    /// 1e308 (finite, but overflows in arithmetic).
    Huge,
    /// 1e999 (overflows to ∞ when parsed).
    Overflow,
    /// −1.
    MinusOne,
    /// 0.
    Zero,
    /// −0.
    MinusZero,
    /// Nothing.
    Empty,
    /// 2⁶⁴ (one past `u64::MAX`).
    BigInt,
    /// 2³² (one past `u32::MAX`).
    U32Overflow,
    /// An integer in ±10 000 000 (frame numbers stay small: huge allocations are another
    /// branch's subject).
    Int(i64),
    /// Any finite float.
    Float(f64),
    /// A float between 0 and 1 (probabilities, shares).
    Unit(f64),
    /// Some text.
    Text(String),
    /// A number padded with spaces.
    Padded(i64),
    /// A quoted field holding a separator.
    Quoted,
    /// TOML-only shapes: an array, an inline table, a boolean.
    Array(Vec<f64>),
    /// `{}`.
    Table,
    /// `true`.
    Bool,
}

impl Value {
    /// The value as text in `syntax`.
    pub fn render(&self, syntax: Syntax) -> String {
        let toml = syntax == Syntax::Toml;
        let float = |x: f64| {
            if toml {
                if x.is_nan() {
                    "nan".to_owned()
                } else if x.is_infinite() {
                    if x > 0.0 { "inf" } else { "-inf" }.to_owned()
                } else {
                    format!("{x:?}")
                }
            } else {
                format!("{x}")
            }
        };
        match self {
            Value::Nan => float(f64::NAN),
            Value::Inf => float(f64::INFINITY),
            Value::NegInf => float(f64::NEG_INFINITY),
            Value::Huge => "1e308".into(),
            Value::Overflow => "1e999".into(),
            Value::MinusOne => "-1".into(),
            Value::Zero => "0".into(),
            Value::MinusZero => if toml { "-0.0" } else { "-0" }.into(),
            Value::Empty => String::new(),
            Value::BigInt => "18446744073709551616".into(),
            Value::U32Overflow => "4294967296".into(),
            Value::Int(i) => i.to_string(),
            Value::Float(x) | Value::Unit(x) => float(*x),
            Value::Text(s) if toml => format!("{s:?}"),
            Value::Text(s) => s.clone(),
            Value::Padded(i) => format!("  {i} "),
            Value::Quoted => "\"1,2\"".into(),
            Value::Array(v) => format!(
                "[{}]",
                v.iter().map(|x| float(*x)).collect::<Vec<_>>().join(", ")
            ),
            Value::Table => "{}".into(),
            Value::Bool => "true".into(),
        }
    }
}

fn value() -> impl Strategy<Value = Value> {
    prop_oneof![
        1 => Just(Value::Nan),
        1 => Just(Value::Inf),
        1 => Just(Value::NegInf),
        1 => Just(Value::Huge),
        1 => Just(Value::Overflow),
        1 => Just(Value::MinusOne),
        1 => Just(Value::Zero),
        1 => Just(Value::MinusZero),
        1 => Just(Value::Empty),
        1 => Just(Value::BigInt),
        1 => Just(Value::U32Overflow),
        3 => (-10_000_000i64..=10_000_000).prop_map(Value::Int),
        2 => (-10i64..=20).prop_map(Value::Int),
        2 => any::<f64>()
            .prop_filter("finite", |x| x.is_finite())
            .prop_map(Value::Float),
        2 => (-1e4f64..1e4).prop_map(Value::Float),
        2 => (0.0f64..=1.0).prop_map(Value::Unit),
        1 => "[ -~é\u{feff}]{0,8}".prop_map(Value::Text),
        1 => (-5i64..50).prop_map(Value::Padded),
        1 => Just(Value::Quoted),
        1 => proptest::collection::vec(
            prop_oneof![Just(f64::NAN), Just(f64::INFINITY), -1e3f64..1e3],
            0..12
        )
        .prop_map(Value::Array),
        1 => Just(Value::Table),
        1 => Just(Value::Bool),
    ]
}

/// One structured change to a file. Positions are [`Index`]es, scaled to the file at hand.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// Replaces field `field` of line `line` with a value.
    Set(Index, Index, Value),
    /// Removes field `field` of every line (a column cut out).
    CutColumn(Index),
    /// Removes field `field` of one line.
    CutField(Index, Index),
    /// Repeats a line right after itself.
    DuplicateLine(Index),
    /// Removes a line.
    DeleteLine(Index),
    /// Swaps two lines.
    SwapLines(Index, Index),
    /// Appends a field to every line (`None`) or to one.
    ExtraColumn(Option<Index>),
    /// Inserts an empty line.
    BlankLine(Index),
    /// Puts a UTF-8 byte-order mark in front.
    Bom,
    /// Ends every line with CRLF.
    Crlf,
    /// Cuts the file at a byte.
    Truncate(Index),
    /// Inserts bytes at a position.
    Insert(Index, Vec<u8>),
    /// Overwrites one byte.
    Overwrite(Index, u8),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        12 => (any::<Index>(), any::<Index>(), value()).prop_map(|(l, f, v)| Mutation::Set(l, f, v)),
        1 => any::<Index>().prop_map(Mutation::CutColumn),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(l, f)| Mutation::CutField(l, f)),
        1 => any::<Index>().prop_map(Mutation::DuplicateLine),
        1 => any::<Index>().prop_map(Mutation::DeleteLine),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        1 => proptest::option::of(any::<Index>()).prop_map(Mutation::ExtraColumn),
        1 => any::<Index>().prop_map(Mutation::BlankLine),
        1 => Just(Mutation::Bom),
        1 => Just(Mutation::Crlf),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        1 => (
            any::<Index>(),
            proptest::collection::vec(any::<u8>(), 1..6)
        )
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        1 => (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::Overwrite(i, b)),
    ]
}

/// A fuzz case: a seed file with mutations, or raw bytes.
#[derive(Debug, Clone)]
pub enum Case {
    /// Seed number `.0` (index into the seeds) with mutations applied in order.
    Mutated(Index, Vec<Mutation>),
    /// Random bytes.
    Raw(Vec<u8>),
}

impl Case {
    /// The bytes of the case.
    pub fn render(&self, seeds: &[&str], syntax: Syntax) -> Vec<u8> {
        match self {
            Case::Raw(b) => b.clone(),
            Case::Mutated(seed, muts) => {
                let mut bytes = seeds[seed.index(seeds.len())].as_bytes().to_vec();
                for m in muts {
                    bytes = apply(&bytes, m, syntax);
                }
                bytes
            }
        }
    }
}

/// Cases over `seeds`: nine in ten mutate a seed, one in ten is raw bytes.
pub fn cases() -> impl Strategy<Value = Case> {
    prop_oneof![
        9 => (any::<Index>(), proptest::collection::vec(mutation(), 1..4))
            .prop_map(|(s, m)| Case::Mutated(s, m)),
        1 => proptest::collection::vec(any::<u8>(), 0..200).prop_map(Case::Raw),
    ]
}

fn split_lines(bytes: &[u8]) -> Vec<Vec<u8>> {
    bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect()
}

fn split_fields(line: &[u8], sep: u8) -> Vec<Vec<u8>> {
    line.split(|&b| b == sep).map(<[u8]>::to_vec).collect()
}

fn apply(bytes: &[u8], m: &Mutation, syntax: Syntax) -> Vec<u8> {
    let sep = syntax.separator();
    let mut lines = split_lines(bytes);
    let n = lines.len();
    let join_fields = |f: Vec<Vec<u8>>| f.join(&sep);
    match m {
        Mutation::Set(l, f, v) => {
            let li = l.index(n);
            let mut fields = split_fields(&lines[li], sep);
            let fi = f.index(fields.len());
            let mut text = v.render(syntax);
            if syntax != Syntax::Csv && fi > 0 {
                text.insert(0, ' ');
            }
            fields[fi] = text.into_bytes();
            lines[li] = join_fields(fields);
        }
        Mutation::CutColumn(f) => {
            let width = lines
                .iter()
                .map(|l| split_fields(l, sep).len())
                .max()
                .unwrap_or(1);
            let fi = f.index(width);
            for l in &mut lines {
                let mut fields = split_fields(l, sep);
                if fi < fields.len() && fields.len() > 1 {
                    fields.remove(fi);
                }
                *l = join_fields(fields);
            }
        }
        Mutation::CutField(l, f) => {
            let li = l.index(n);
            let mut fields = split_fields(&lines[li], sep);
            fields.remove(f.index(fields.len()));
            lines[li] = join_fields(fields);
        }
        Mutation::DuplicateLine(l) => {
            let li = l.index(n);
            let copy = lines[li].clone();
            lines.insert(li, copy);
        }
        Mutation::DeleteLine(l) => {
            lines.remove(l.index(n));
        }
        Mutation::SwapLines(a, b) => lines.swap(a.index(n), b.index(n)),
        Mutation::ExtraColumn(which) => {
            let extra = match syntax {
                Syntax::Csv => b",extra".to_vec(),
                Syntax::Ini | Syntax::Toml => b" = 1".to_vec(),
            };
            match which {
                None => lines.iter_mut().for_each(|l| l.extend_from_slice(&extra)),
                Some(l) => lines[l.index(n)].extend_from_slice(&extra),
            }
        }
        Mutation::BlankLine(l) => lines.insert(l.index(n + 1), Vec::new()),
        Mutation::Bom => {
            let mut out = "\u{feff}".as_bytes().to_vec();
            out.extend_from_slice(bytes);
            return out;
        }
        Mutation::Crlf => {
            for l in &mut lines {
                if l.last() != Some(&b'\r') {
                    l.push(b'\r');
                }
            }
            // The part after the last newline is not a line end.
            if let Some(last) = lines.last_mut()
                && last == b"\r"
            {
                last.clear();
            }
        }
        Mutation::Truncate(i) => return bytes[..i.index(bytes.len() + 1)].to_vec(),
        Mutation::Insert(i, b) => {
            let at = i.index(bytes.len() + 1);
            let mut out = bytes[..at].to_vec();
            out.extend_from_slice(b);
            out.extend_from_slice(&bytes[at..]);
            return out;
        }
        Mutation::Overwrite(i, b) => {
            let mut out = bytes.to_vec();
            if !out.is_empty() {
                let at = i.index(out.len());
                out[at] = *b;
            }
            return out;
        }
    }
    lines.join(&b'\n')
}

/// The seed of the generator of test `name` (a fixed function of the name, so every run and
/// every machine sees the same cases).
fn seed_of(name: &str) -> [u8; 32] {
    let mut seed = *b"roadtrack fuzz, issue 15 part 5.";
    // FNV-1a over the name, folded into the seed.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in name.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    for (i, s) in seed.iter_mut().enumerate() {
        *s ^= (h >> ((i % 8) * 8)) as u8;
    }
    seed
}

/// The input as a Rust byte-string literal (for a regression test).
pub fn literal(bytes: &[u8]) -> String {
    format!("b\"{}\"", bytes.escape_ascii())
}

/// Runs `cases` fuzz cases of `check` over mutations of `seeds` (and raw bytes), seeded by
/// `name`. `check` gets the bytes of the case and returns `Err` with a reason when the
/// outcome is not allowed; a panic is a failure too. Fails the test with the smallest
/// failing input found, printed as a byte-string literal.
pub fn run(
    name: &str,
    cases_n: u32,
    seeds: &[&str],
    syntax: Syntax,
    check: impl Fn(&[u8]) -> Result<(), String>,
) {
    let config = Config {
        cases: cases_n,
        failure_persistence: None,
        max_shrink_iters: 4096,
        ..Config::default()
    };
    let mut runner = TestRunner::new_with_rng(
        config,
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed_of(name)),
    );
    let result = runner.run(&cases(), |case| {
        let bytes = case.render(seeds, syntax);
        match catch_unwind(AssertUnwindSafe(|| check(&bytes))) {
            Ok(Ok(())) => Ok(()),
            Ok(Err(why)) => Err(TestCaseError::fail(format!(
                "{why}\ninput: {}",
                literal(&bytes)
            ))),
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                Err(TestCaseError::fail(format!(
                    "panic: {msg}\ninput: {}",
                    literal(&bytes)
                )))
            }
        }
    });
    if let Err(e) = result {
        panic!("fuzz {name}: {e}");
    }
}

/// Number of lines of `bytes` as a reader counts them (a last line without newline counts).
pub fn line_count(bytes: &[u8]) -> u64 {
    bytes.iter().filter(|&&b| b == b'\n').count() as u64 + 1
}

/// Writes the case to `path`, replacing the previous one.
// Choice: the old file is removed first; rewriting it in place (truncate and write) makes
// ext4 flush it to disk on close, which made the tests wait on the disk, not the CPU.
pub fn write_case(path: &std::path::Path, bytes: &[u8]) -> Result<(), String> {
    match std::fs::remove_file(path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(format!("cannot remove the last case: {e}")),
    }
    std::fs::write(path, bytes).map_err(|e| format!("cannot write the case: {e}"))
}

/// An error is allowed when it names `path` (and, for a parse error, a line of the file).
pub fn file_error(
    e: &roadtrack_core::Error,
    path: &std::path::Path,
    bytes: &[u8],
) -> Result<(), String> {
    match e {
        roadtrack_core::Error::Parse { path: p, line, .. } if p == path => {
            let lines = line_count(bytes);
            if *line >= 1 && *line <= lines {
                Ok(())
            } else {
                Err(format!("line {line} outside 1..={lines}: {e}"))
            }
        }
        roadtrack_core::Error::Format { path: p, .. } if p == path => Ok(()),
        other => Err(format!("unexpected error kind: {other:?}")),
    }
}
