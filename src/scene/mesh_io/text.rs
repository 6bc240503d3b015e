//! Text mesh files (ASCII STL, OFF): read in blocks of whole lines through two reused buffers
//! (the next block is read while the current one is parsed), lines with their numbers and byte
//! offsets, whitespace-separated tokens, and numbers parsed as `str::parse` does (correctly
//! rounded), with a fast path for plain decimals.

use super::shared::{check_size, file_len, reserve, MAX_LINE_BYTES};
use std::io::Read;
use std::path::Path;

/// How a text file is cut: `block` bytes read and parsed at once (whole lines; more where one
/// line is longer), in pieces of about `piece` bytes parsed in parallel.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cuts {
    pub block: usize,
    pub piece: usize,
}

/// The cuts of text mesh files: blocks of 4 MiB (a line of [`MAX_LINE_BYTES`] fits), pieces of
/// 512 KiB.
pub(super) const CUTS: Cuts = Cuts {
    block: 4 << 20,
    piece: 512 << 10,
};

/// Reads the text file `path` in consecutive blocks of whole lines (the last may end without a
/// line end), about `block` bytes each, and calls `each(block, offset)` on them in order while
/// the next block is read; `each` returns `false` to stop early. A line longer than a block is
/// read on to its end, or until it is longer than [`MAX_LINE_BYTES`] (then `each` is given it to
/// refuse). The file's size is checked against the limit, and reading stops at it.
pub(super) fn for_each_block(
    path: &Path,
    block: usize,
    mut each: impl FnMut(&[u8], u64) -> Result<bool, String> + Send,
) -> Result<(), String> {
    file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let (mut current, mut next) = (Vec::new(), Vec::new());
    reserve(&mut current, block as u64, "a read buffer")?;
    reserve(&mut next, block as u64, "a read buffer")?;
    let mut eof = fill(&mut file, &mut current, block)?;
    let mut offset = 0u64;
    loop {
        let mut cut = memchr::memrchr(b'\n', &current).map(|end| end + 1);
        while cut.is_none() && !eof && current.len() <= MAX_LINE_BYTES {
            let more = current.len() + block;
            reserve(&mut current, block as u64, "a read buffer")?;
            eof = fill(&mut file, &mut current, more)?;
            cut = memchr::memrchr(b'\n', &current).map(|end| end + 1);
        }
        let cut = if eof {
            current.len()
        } else {
            cut.unwrap_or(current.len())
        };
        if cut == 0 {
            return Ok(());
        }
        next.clear();
        next.extend_from_slice(&current[cut..]);
        let (more, read) = rayon::join(
            || each(&current[..cut], offset),
            || {
                if eof {
                    Ok(true)
                } else {
                    fill(&mut file, &mut next, block)
                }
            },
        );
        if !more? {
            return Ok(());
        }
        eof = read?;
        offset += cut as u64;
        check_size(offset)?;
        std::mem::swap(&mut current, &mut next);
    }
}

/// Reads into `buffer` until it holds `target` bytes or the file ends; true at the end.
fn fill(file: &mut std::fs::File, buffer: &mut Vec<u8>, target: usize) -> Result<bool, String> {
    let want = target.saturating_sub(buffer.len()) as u64;
    if want == 0 {
        return Ok(false);
    }
    let got = Read::take(&mut *file, want)
        .read_to_end(buffer)
        .map_err(|e| e.to_string())?;
    Ok((got as u64) < want)
}

/// The lines of a block of a text file, each bounded by [`MAX_LINE_BYTES`], with the current
/// line's number (from 1) and byte offset.
pub(super) struct TextLines<'a> {
    text: &'a [u8],
    /// `text` when it is all UTF-8 (checked at once), so its lines need no check of their own.
    checked: Option<&'a str>,
    rest: &'a [u8],
    /// The number of the line last read (1 for the file's first; one past the last at the end).
    pub line: u64,
    /// The byte offset where the line last read starts.
    pub offset: u64,
    next_offset: u64,
}

impl<'a> TextLines<'a> {
    /// The lines of `text`, which starts at byte `offset` of its file, after `lines` lines.
    pub fn new(text: &'a [u8], offset: u64, lines: u64) -> Self {
        Self {
            text,
            checked: std::str::from_utf8(text).ok(),
            rest: text,
            line: lines,
            offset,
            next_offset: offset,
        }
    }

    /// Where the last line is: `line N (byte B)`.
    pub fn at(&self) -> String {
        format!("line {} (byte {})", self.line, self.offset)
    }

    /// The bytes of `text` read so far (whole lines).
    pub fn consumed(&self) -> usize {
        self.text.len() - self.rest.len()
    }

    /// The text not read yet, where it is known to be UTF-8: then a reader may take a line from
    /// it itself (with [`Fast`]) and count it read with [`TextLines::skip_line`].
    #[inline]
    pub fn unread(&self) -> Option<&'a [u8]> {
        self.checked.map(|_| self.rest)
    }

    /// Counts the next `n` bytes of the text (one whole line, with its line end) as read.
    #[inline]
    pub fn skip_line(&mut self, n: usize) {
        self.line += 1;
        self.offset = self.next_offset;
        self.rest = &self.rest[n..];
        self.next_offset += n as u64;
    }

    /// The next line without its line ending (`None` at the end). A line that is not UTF-8 or
    /// longer than [`MAX_LINE_BYTES`] is an error naming it.
    #[inline]
    pub fn next_line(&mut self) -> Result<Option<&'a str>, String> {
        self.line += 1;
        self.offset = self.next_offset;
        if self.rest.is_empty() {
            return Ok(None);
        }
        let (line, taken) = match memchr::memchr(b'\n', self.rest) {
            Some(end) => (&self.rest[..end], end + 1),
            None => (self.rest, self.rest.len()),
        };
        self.rest = &self.rest[taken..];
        self.next_offset += taken as u64;
        if line.len() > MAX_LINE_BYTES {
            return Err(format!(
                "{}: longer than {MAX_LINE_BYTES} bytes (a binary file, or not this format?)",
                self.at()
            ));
        }
        let mut end = line.len();
        while end > 0 && line[end - 1] == b'\r' {
            end -= 1;
        }
        if let Some(text) = self.checked {
            // the line's start and end are at ASCII bytes, so on character boundaries
            let start = self.text.len() - self.rest.len() - taken;
            return text
                .get(start..start + end)
                .map(Some)
                .ok_or_else(|| format!("{}: not text (invalid UTF-8)", self.at()));
        }
        std::str::from_utf8(&line[..end])
            .map(Some)
            .map_err(|_| format!("{}: not text (invalid UTF-8)", self.at()))
    }
}

/// The starts of up to `count` pieces of `text` (the first at 0) at line starts near equal
/// shares, each chosen by `fits(line)` (a line start where a piece may begin), and the end.
pub(super) fn piece_starts(text: &[u8], count: usize, fits: impl Fn(&[u8]) -> bool) -> Vec<usize> {
    let next_line = |at: usize| memchr::memchr(b'\n', &text[at..]).map_or(text.len(), |i| at + i + 1);
    let mut starts = vec![0];
    for k in 1..count {
        let from = (text.len() / count * k).max(starts[starts.len() - 1] + 1);
        let mut at = next_line(from - 1);
        while at < text.len() && !fits(&text[at..]) {
            at = next_line(at);
        }
        if at < text.len() {
            starts.push(at);
        }
    }
    starts.push(text.len());
    starts
}

/// How many pieces a block of `len` bytes is parsed in: about one per `piece` bytes, at most two
/// per thread.
pub(super) fn piece_count(len: usize, piece: usize) -> usize {
    (len / piece.max(1)).clamp(1, 2 * rayon::current_num_threads())
}

/// The ASCII-whitespace-separated tokens of a line (as `str::split_ascii_whitespace`), or of
/// its part before a `#` (as `split('#').next()` first).
pub(super) struct Tokens<'a> {
    bytes: &'a [u8],
    comments: bool,
}

impl<'a> Tokens<'a> {
    /// The tokens of `line`.
    pub fn new(line: &'a str) -> Self {
        Self {
            bytes: line.as_bytes(),
            comments: false,
        }
    }

    /// The tokens of `line` before a `#`.
    pub fn before_comment(line: &'a str) -> Self {
        Self {
            bytes: line.as_bytes(),
            comments: true,
        }
    }

    /// The next token, if any.
    #[inline]
    pub fn next_token(&mut self) -> Option<&'a [u8]> {
        let b = self.bytes;
        let start = b.iter().position(|c| !c.is_ascii_whitespace())?;
        if self.comments && b[start] == b'#' {
            self.bytes = &[];
            return None;
        }
        let len = b[start..]
            .iter()
            .position(|&c| c.is_ascii_whitespace() || (self.comments && c == b'#'))
            .unwrap_or(b.len() - start);
        self.bytes = &b[start + len..];
        Some(&b[start..start + len])
    }
}

/// A reader of one line in the common layout of a text mesh file: words and numbers separated by
/// spaces or tabs. Each step gives `None` where the line is any other way (a comment, another
/// separator, a number the fast path of [`fast_f32`] does not decide, an error): then the line is
/// read by the general reader instead, which gives the same result or the error.
pub(super) struct Fast<'a> {
    b: &'a [u8],
    i: usize,
}

impl<'a> Fast<'a> {
    pub fn new(line: &'a [u8]) -> Self {
        Self { b: line, i: 0 }
    }

    #[inline(always)]
    fn spaces(&mut self) {
        while let Some(b' ' | b'\t') = self.b.get(self.i) {
            self.i += 1;
        }
    }

    /// Whether a token ends at byte `i` (ASCII whitespace or the end follows).
    #[inline(always)]
    fn ends(&self, i: usize) -> bool {
        self.b.get(i).is_none_or(u8::is_ascii_whitespace)
    }

    /// The word `w` (exactly), after spaces.
    #[inline(always)]
    pub fn word(&mut self, w: &[u8]) -> Option<()> {
        self.spaces();
        let end = self.i + w.len();
        (self.b.get(self.i..end)? == w && self.ends(end)).then(|| self.i = end)
    }

    /// A coordinate, after spaces.
    #[inline(always)]
    pub fn f32(&mut self) -> Option<f32> {
        self.spaces();
        let (x, n) = decimal(&self.b[self.i..])?;
        self.i += n;
        self.ends(self.i).then_some(x)
    }

    /// An unsigned integer of at most 9 digits, after spaces.
    #[inline(always)]
    pub fn u32(&mut self) -> Option<u32> {
        self.spaces();
        let start = self.i;
        let mut n = 0u32;
        while let Some(&c) = self.b.get(self.i) {
            let d = c.wrapping_sub(b'0');
            if d > 9 || self.i - start == 9 {
                break;
            }
            n = n * 10 + u32::from(d);
            self.i += 1;
        }
        (self.i > start && self.ends(self.i)).then_some(n)
    }

    /// The end of the line after optional spaces: the bytes of the line with its line end.
    #[inline(always)]
    pub fn end(&mut self) -> Option<usize> {
        while let Some(b' ' | b'\t' | b'\r') = self.b.get(self.i) {
            self.i += 1;
        }
        match self.b.get(self.i) {
            _ if self.i > MAX_LINE_BYTES => None,
            None => Some(self.i),
            Some(b'\n') => Some(self.i + 1),
            Some(_) => None,
        }
    }

    /// The end of the line, whatever the rest holds: the bytes of the line with its line end.
    #[inline(always)]
    pub fn rest_of_line(&self) -> Option<usize> {
        let rest = &self.b[self.i..];
        let (len, taken) = match memchr::memchr(b'\n', rest) {
            Some(end) => (self.i + end, self.i + end + 1),
            None => (self.b.len(), self.b.len()),
        };
        (len <= MAX_LINE_BYTES).then_some(taken)
    }
}

/// A token as text, for messages (tokens are cut from valid UTF-8 at ASCII whitespace).
pub(super) fn show(token: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(token)
}

/// Parses a finite `f32` coordinate token; the error names `what` (`what()` is only called for
/// an error).
#[inline]
pub(super) fn coordinate<W: std::fmt::Display>(token: Option<&[u8]>, what: impl Fn() -> W) -> Result<f32, String> {
    let token = token.ok_or_else(|| format!("{}: missing", what()))?;
    let x = parse_f32(token).ok_or_else(|| format!("{}: `{}` is not a number", what(), show(token)))?;
    if !x.is_finite() {
        return Err(format!("{}: `{}` is not finite", what(), show(token)));
    }
    Ok(x)
}

/// Parses `token` as `str::parse::<f32>` does (the same numbers, correctly rounded, the same
/// refusals): plain decimals by [`fast_f32`], anything else by the standard library.
#[inline]
pub(super) fn parse_f32(token: &[u8]) -> Option<f32> {
    match fast_f32(token) {
        Some(x) => Some(x),
        None => std::str::from_utf8(token).ok()?.parse().ok(),
    }
}

/// Powers of ten `10^k` and `10^-k` for `k ≤ 22`, each correctly rounded to `f64`.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20,
    1e21, 1e22,
];
const POW10_NEG: [f64; 23] = [
    1e0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15, 1e-16, 1e-17,
    1e-18, 1e-19, 1e-20, 1e-21, 1e-22,
];

/// 2¹²⁷, where the top binade of `f32` starts.
const F32_TOP_BINADE: f64 = 170_141_183_460_469_231_731_687_303_715_884_105_728.0;

/// The value of 8 ASCII digits at the start of `b` (the first most significant), if there are.
#[inline(always)]
fn eight_digits(b: &[u8]) -> Option<u64> {
    let v = u64::from_le_bytes(b.get(..8)?.try_into().ok()?);
    // every byte 0x30..=0x3f, and still below 0x40 with 6 added: '0'..='9'
    const HIGH: u64 = 0xf0f0_f0f0_f0f0_f0f0;
    const ZEROS: u64 = 0x3030_3030_3030_3030;
    if v & HIGH != ZEROS || v.wrapping_add(0x0606_0606_0606_0606) & HIGH != ZEROS {
        return None;
    }
    // byte k holds digit k; combine neighbours into 2-, 4-, then 8-digit values (no carries)
    let v = v - ZEROS;
    let v = (v.wrapping_mul(10) + (v >> 8)) & 0x00ff_00ff_00ff_00ff;
    let v = (v.wrapping_mul(100) + (v >> 16)) & 0x0000_ffff_0000_ffff;
    Some((v.wrapping_mul(10_000) + (v >> 32)) & 0xffff_ffff)
}

/// A decimal `[+-]digits[.digits][(e|E)[+-]digits]` with at most 19 significant digits and a
/// decimal exponent within ±22, as the correctly rounded `f32`; `None` where this fast path does
/// not decide (the caller then parses with the standard library).
///
/// The significand `m` (exact in `u64`) times `10^e`, both rounded to `f64` and multiplied, is
/// within 3 units in the last place (`f64`) of the decimal's value. Where that `f64` is more than
/// 8 units from every point halfway between two `f32`s (the midpoints of a binade are where the
/// 29 low bits of an `f64` are `1000…0`), the decimal lies on the same side of each, so rounding
/// the `f64` to `f32` rounds the decimal correctly. Results near a midpoint, or outside the
/// normal `f32` binades `[2⁻¹²⁶, 2¹²⁷)`, are left to the standard library.
#[inline]
pub(super) fn fast_f32(token: &[u8]) -> Option<f32> {
    decimal(token).and_then(|(x, n)| (n == token.len()).then_some(x))
}

/// The decimal at the start of `text` as [`fast_f32`] reads it, and its length: the longest
/// prefix of the form, where the fast path decides it.
#[inline(always)]
fn decimal(text: &[u8]) -> Option<(f32, usize)> {
    let (negative, b) = match text.first()? {
        b'-' => (true, &text[1..]),
        b'+' => (false, &text[1..]),
        _ => (false, text),
    };
    let signed = text.len() - b.len();
    let digit = |i: usize| b.get(i).map(|c| c.wrapping_sub(b'0')).filter(|&d| d <= 9);
    // the digits from `i` on, accumulated into `m`
    let digits = |i: &mut usize, m: &mut u64| {
        while let Some(x) = b.get(*i..).and_then(eight_digits) {
            *m = m.wrapping_mul(100_000_000).wrapping_add(x);
            *i += 8;
        }
        while let Some(d) = digit(*i) {
            *m = m.wrapping_mul(10).wrapping_add(u64::from(d));
            *i += 1;
        }
    };
    // the integer part, its leading zeros skipped
    let mut i = 0;
    while b.get(i) == Some(&b'0') {
        i += 1;
    }
    let mut m: u64 = 0;
    let first = i;
    digits(&mut i, &mut m);
    let mut significant = i - first;
    let mut any = i > 0;
    let mut scale = 0i64;
    if b.get(i) == Some(&b'.') {
        i += 1;
        let fraction = i;
        if m == 0 {
            while b.get(i) == Some(&b'0') {
                i += 1;
            }
        }
        let first = i;
        digits(&mut i, &mut m);
        significant += i - first;
        scale = -((i - fraction) as i64);
        any |= i > fraction;
    }
    if !any || significant > 19 {
        return None;
    }
    if let Some(b'e' | b'E') = b.get(i) {
        i += 1;
        let sign = match b.get(i) {
            Some(b'-') => {
                i += 1;
                -1
            }
            Some(b'+') => {
                i += 1;
                1
            }
            _ => 1,
        };
        let start = i;
        let mut e = 0i64;
        while let Some(d) = digit(i) {
            if i - start >= 4 {
                return None;
            }
            e = e * 10 + i64::from(d);
            i += 1;
        }
        if i == start {
            return None;
        }
        scale += sign * e;
    }
    if m == 0 {
        return Some((if negative { -0.0 } else { 0.0 }, signed + i));
    }
    let power = match usize::try_from(scale) {
        Ok(k) => *POW10.get(k)?,
        Err(_) => *POW10_NEG.get(usize::try_from(-scale).ok()?)?,
    };
    let r = m as f64 * power;
    let low = r.to_bits() & ((1 << 29) - 1);
    if !(f64::from(f32::MIN_POSITIVE)..F32_TOP_BINADE).contains(&r) || low.abs_diff(1 << 28) <= 8 {
        return None;
    }
    let x = r as f32;
    Some((if negative { -x } else { x }, signed + i))
}

/// Parses a non-negative integer token as `str::parse::<u64>` does (digits, an optional `+`).
#[inline]
pub(super) fn parse_u64(token: &[u8]) -> Option<u64> {
    if !token.is_empty() && token.len() <= 18 && token.iter().all(u8::is_ascii_digit) {
        return Some(token.iter().fold(0, |n, &c| n * 10 + u64::from(c - b'0')));
    }
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Parses an integer token as `str::parse::<i64>` does.
#[inline]
pub(super) fn parse_i64(token: &[u8]) -> Option<i64> {
    if !token.is_empty() && token.len() <= 18 && token.iter().all(u8::is_ascii_digit) {
        return Some(token.iter().fold(0, |n, &c| n * 10 + i64::from(c - b'0')));
    }
    std::str::from_utf8(token).ok()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn check(s: &str) {
        let want = s.parse::<f32>().ok();
        let got = parse_f32(s.as_bytes());
        assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "`{s}`");
    }

    #[test]
    fn floats_parse_as_the_standard_library_does() {
        let fixed = [
            "0",
            "-0",
            "+0",
            "0.0",
            "-0.0",
            "1",
            "1.",
            ".5",
            "-.5",
            ".",
            "-",
            "+",
            "",
            "e5",
            "1e",
            "1e+",
            "1e-",
            "1e5",
            "1E-5",
            "1e+38",
            "3.4028235e38",
            "3.4028236e38",
            "1e39",
            "1e-38",
            "1e-45",
            "1e-46",
            "1.17549435e-38",
            "16777217",
            "16777219",
            "33554434",
            "33554435",
            "0.1",
            "0.2",
            "0.3",
            "1.5e-7",
            "nan",
            "NaN",
            "inf",
            "-inf",
            "infinity",
            "1..2",
            "1.2.3",
            "1e5e5",
            "0x10",
            "1_0",
            " 1",
            "1 ",
            "00000000000000000000000001.5",
            "1.00000005960464477539",
            "1.0000000596046447753906250001",
            "9007199254740993",
            "9007199254740992",
            "12345678901234567890",
            "1234567890123456789",
            "1e-22",
            "1e22",
            "1e23",
            "4e-22",
            "123456789e-30",
            "0.000000000000000000000000000001",
            "1e0000001",
            "1e00001",
            "-1.17549421e-38",
            "1.4e-45",
            "1.e5",
            ".e5",
            "1.E-2",
            "-.0",
            "0.",
            "+-1",
            "--1",
            "1e-0",
            "0.000000001234567",
            "1234567.125",
            "-0e5",
            "12345678",
            "123456789012345678",
            "0.12345678",
            "1234567a",
            "1234567:",
            "1234567/",
            "12345678.87654321",
            "99999999e-8",
            "0.0000000000000000000000000000000000000117549435",
            "340282356779733661637539395458142568448",
        ];
        for s in fixed {
            check(s);
        }
    }

    #[test]
    fn random_floats_parse_as_the_standard_library_does() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(45);
        for _ in 0..200_000 {
            let x = f32::from_bits(rng.random());
            check(&x.to_string());
            check(&format!("{x:e}"));
            check(&format!("{x:.3}"));
            let y = rng.random::<f32>() * 20.0 - 10.0;
            check(&y.to_string());
            check(&format!("{y:.9}"));
            check(&format!("{}", f64::from(y) + rng.random::<f64>() * 1e-9));
            // halfway between two f32s, written out in ≤ 17 digits
            let next = f32::from_bits(y.to_bits() + 1);
            check(&format!("{}", (f64::from(y) + f64::from(next)) / 2.0));
            // decimals of 9 to 19 digits just around that midpoint
            let mid = (f64::from(y) + f64::from(next)) / 2.0;
            for precision in [8, 12, 15, 16, 17, 18] {
                check(&format!("{mid:.precision$e}"));
                let s = format!("{mid:.precision$e}");
                let (mantissa, exponent) = s.split_once('e').unwrap();
                let last = mantissa.as_bytes()[mantissa.len() - 1];
                for d in [b'0', b'4', b'5', b'9'] {
                    if d != last {
                        check(&format!("{}{}e{exponent}", &mantissa[..mantissa.len() - 1], d as char));
                    }
                }
            }
            let digits: u64 = rng.random_range(0..10_000_000_000_000_000_000);
            let e: i32 = rng.random_range(-60..60);
            check(&format!("{digits}e{e}"));
            check(&format!("-0.{digits}"));
        }
    }

    #[test]
    fn shortest_f32_decimals_take_the_fast_path() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let fast = (0..10_000)
            .filter(|_| fast_f32((rng.random::<f32>() * 4.0 - 2.0).to_string().as_bytes()).is_some())
            .count();
        assert!(fast > 9_900, "{fast}");
    }

    #[test]
    fn integers_parse_as_the_standard_library_does() {
        for s in [
            "0",
            "7",
            "+7",
            "-7",
            "",
            "-",
            "+",
            "007",
            "1x",
            "18446744073709551615",
            "18446744073709551616",
            "9223372036854775807",
            "9223372036854775808",
            "999999999999999999",
            "1 ",
        ] {
            assert_eq!(parse_u64(s.as_bytes()), s.parse().ok(), "`{s}`");
            assert_eq!(parse_i64(s.as_bytes()), s.parse().ok(), "`{s}`");
        }
    }

    /// Every token `tokens` hands out, as strings.
    fn all_tokens(mut tokens: Tokens<'_>) -> Vec<String> {
        let mut out = Vec::new();
        while let Some(token) = tokens.next_token() {
            out.push(std::str::from_utf8(token).unwrap().to_string());
        }
        out
    }

    /// The standard library's split of `line` into words before its first `#`.
    fn words_before_comment(line: &str) -> Vec<String> {
        line.split('#')
            .next()
            .unwrap()
            .split_ascii_whitespace()
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn lines_and_tokens_split_as_the_standard_library_does() {
        let text = "a b\r\n\n  c\t d \r\r\nlast#x y";
        let mut lines = TextLines::new(text.as_bytes(), 0, 0);
        let mut got = Vec::new();
        while let Some(line) = lines.next_line().unwrap() {
            let want: Vec<_> = line.split_ascii_whitespace().map(str::to_string).collect();
            assert_eq!(all_tokens(Tokens::new(line)), want);
            assert_eq!(all_tokens(Tokens::before_comment(line)), words_before_comment(line));
            got.push((lines.line, lines.offset, line.to_string()));
        }
        assert_eq!(lines.line, 5);
        assert_eq!(got[2], (3, 6, "  c\t d ".to_string()));
        assert_eq!(got[3], (4, 16, "last#x y".to_string()));
        for line in ["#", "a#b c", " a #b", "a b#", "##", " x  y "] {
            assert_eq!(
                all_tokens(Tokens::before_comment(line)),
                words_before_comment(line),
                "{line}"
            );
        }
    }
}
