//! Parsing a large `objects` list in parallel.
//!
//! RON parsing costs about 24,000 instructions per sphere, so a million objects take seconds on
//! one core. [`parse_objects_in_parallel`] finds the top-level elements of the scene's
//! `objects: [...]` list with a small lexer (strings, raw strings, characters, nested comments and
//! brackets), parses the rest of the file with an empty list, and the elements in chunks on as
//! many threads as the machine has. Any difficulty — no such list, fewer than
//! [`PARALLEL_OBJECTS`] elements, inner attributes (`#![enable(...)]`), a chunk that does not
//! parse — returns `None`, and the caller parses the whole text as usual, so errors keep their
//! exact line and column and a successful parse always gives the same descriptions.

use crate::scene::{ron_options, ObjectDesc, SceneDesc, PARSE_STACK_BYTES};
use std::ops::Range;

/// Lists shorter than this are parsed in one piece.
pub const PARALLEL_OBJECTS: usize = 20_000;

/// `text` parsed with its `objects` list split over threads, or `None` (see the module docs).
pub(crate) fn parse_objects_in_parallel(text: &str) -> Option<SceneDesc> {
    if text.contains("#![") {
        return None;
    }
    let (list, elements) = objects_list(text)?;
    if elements.len() < PARALLEL_OBJECTS {
        return None;
    }
    let skeleton = format!("{}{}", &text[..list.start], &text[list.end..]);
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(1, 64);
    let per_chunk = elements.len().div_ceil(threads);
    let (chunks, skeleton) = std::thread::scope(|scope| {
        let workers: Vec<_> = elements
            .chunks(per_chunk)
            .map(|chunk| {
                let range = chunk[0].start..chunk[chunk.len() - 1].end;
                let expected = chunk.len();
                std::thread::Builder::new()
                    .name("scene parser".into())
                    .stack_size(PARSE_STACK_BYTES)
                    .spawn_scoped(scope, move || {
                        // the chunk's elements as one list (one parser per chunk: a parser per
                        // element costs 17 % more instructions, measured)
                        let source = format!("[{}]", &text[range]);
                        let objects: Vec<ObjectDesc> = ron_options().from_str(&source).ok()?;
                        (objects.len() == expected).then_some(objects)
                    })
            })
            .collect();
        // the rest of the scene on this thread meanwhile (its stack is the parser's)
        let skeleton = ron_options().from_str::<SceneDesc>(&skeleton).ok();
        let chunks: Vec<Option<Vec<ObjectDesc>>> = workers
            .into_iter()
            .map(|w| w.ok().and_then(|handle| handle.join().ok().flatten()))
            .collect();
        (chunks, skeleton)
    });
    let mut desc = skeleton?;
    if !desc.objects.is_empty() {
        return None;
    }
    desc.objects.reserve_exact(elements.len());
    for chunk in chunks {
        desc.objects.extend(chunk?);
    }
    Some(desc)
}

/// The byte range inside the brackets of the top-level `objects: [...]`, and the ranges of its
/// elements (trimmed, without separating commas), or `None` if the lexer is unsure.
fn objects_list(text: &str) -> Option<(Range<usize>, Vec<Range<usize>>)> {
    let bytes = text.as_bytes();
    let mut lexer = Lexer { bytes, at: 0 };
    let mut depth = 0usize;
    // find `objects` `:` `[` at depth 1
    let list_start = loop {
        match lexer.token()? {
            Token::Open => depth += 1,
            Token::Close => depth = depth.checked_sub(1)?,
            Token::Ident(range) if depth == 1 && &bytes[range.clone()] == b"objects" => {
                if lexer.token()? != Token::Colon || lexer.token()? != Token::Open || bytes[lexer.at - 1] != b'[' {
                    return None;
                }
                break lexer.at;
            }
            Token::End => return None,
            _ => {}
        }
    };
    let (list_end, elements) = list_elements(text, list_start)?;
    Some((list_start..list_end, elements))
}

/// Bytes the element scan must look at; everything else (digits, letters, spaces) is skipped
/// one table lookup per byte.
const SPECIAL: [bool; 256] = {
    let mut table = [false; 256];
    let mut k = 0;
    let specials = b"()[]{},\"'/r";
    while k < specials.len() {
        table[specials[k] as usize] = true;
        k += 1;
    }
    table
};

/// The elements of a list whose `[` ends just before `start`: separated by commas at the list's
/// own depth; returns the position of the closing `]` and the trimmed element ranges.
fn list_elements(text: &str, start: usize) -> Option<(usize, Vec<Range<usize>>)> {
    let bytes = text.as_bytes();
    let mut elements = Vec::new();
    let mut element_start = start;
    let mut depth = 0usize;
    let mut at = start;
    while at < bytes.len() {
        let c = bytes[at];
        if !SPECIAL[c as usize] {
            at += 1;
            continue;
        }
        match c {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b'}' => depth = depth.checked_sub(1)?,
            b']' if depth == 0 => {
                push_trimmed(text, element_start..at, &mut elements);
                return Some((at, elements));
            }
            b']' => depth -= 1,
            b',' if depth == 0 => {
                push_trimmed(text, element_start..at, &mut elements);
                element_start = at + 1;
            }
            b'r' if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_') => {}
            b'"' | b'\'' | b'/' | b'r' => {
                // strings, characters, comments and raw strings: the full lexer skips them
                let mut lexer = Lexer { bytes, at };
                let before = lexer.at;
                match lexer.token()? {
                    Token::End => return None,
                    // a lone `/` or an identifier starting with `r`: one byte on
                    Token::Ident(_) | Token::Other if lexer.at == before + 1 => {}
                    Token::Ident(_) | Token::Other => {
                        at = lexer.at;
                        continue;
                    }
                    // the lexer skipped a comment and read the next token: rescan from it
                    _ => {
                        at = lexer.at - 1;
                        continue;
                    }
                }
            }
            _ => {}
        }
        at += 1;
    }
    None
}

/// Pushes `range` of `text` trimmed of whitespace, unless nothing is left (a trailing comma).
/// Comments stay inside (the parser skips them).
fn push_trimmed(text: &str, range: Range<usize>, out: &mut Vec<Range<usize>>) {
    let slice = &text[range.clone()];
    let start = range.start + (slice.len() - slice.trim_start().len());
    let end = range.end - (slice.len() - slice.trim_end().len());
    if start < end {
        out.push(start..end);
    }
}

#[derive(Debug, PartialEq, Eq)]
enum Token {
    Open,
    Close,
    Comma,
    Colon,
    Ident(Range<usize>),
    Other,
    End,
}

/// The RON lexer, just enough to find brackets and commas outside strings and comments.
struct Lexer<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Lexer<'_> {
    /// The next token; `None` where the text is malformed (unterminated string or comment).
    fn token(&mut self) -> Option<Token> {
        let b = self.bytes;
        loop {
            let Some(&c) = b.get(self.at) else {
                return Some(Token::End);
            };
            match c {
                b' ' | b'\t' | b'\n' | b'\r' => self.at += 1,
                b'/' if b.get(self.at + 1) == Some(&b'/') => {
                    while self.at < b.len() && b[self.at] != b'\n' {
                        self.at += 1;
                    }
                }
                b'/' if b.get(self.at + 1) == Some(&b'*') => {
                    let mut nesting = 0usize;
                    loop {
                        match (b.get(self.at)?, b.get(self.at + 1)) {
                            (b'/', Some(b'*')) => {
                                nesting += 1;
                                self.at += 2;
                            }
                            (b'*', Some(b'/')) => {
                                nesting -= 1;
                                self.at += 2;
                                if nesting == 0 {
                                    break;
                                }
                            }
                            _ => self.at += 1,
                        }
                    }
                }
                _ => break,
            }
        }
        let c = b[self.at];
        let start = self.at;
        self.at += 1;
        Some(match c {
            b'(' | b'[' | b'{' => Token::Open,
            b')' | b']' | b'}' => Token::Close,
            b',' => Token::Comma,
            b':' => Token::Colon,
            b'"' => {
                self.skip_string()?;
                Token::Other
            }
            b'\'' => {
                // a character: `'x'`, `'\''`, `'\u{..}'`
                loop {
                    match *b.get(self.at)? {
                        b'\\' => self.at += 2,
                        b'\'' => {
                            self.at += 1;
                            break;
                        }
                        _ => self.at += 1,
                    }
                }
                Token::Other
            }
            b'r' if matches!(b.get(self.at), Some(b'"' | b'#')) => {
                // a raw string r#"…"#
                let mut hashes = 0;
                while b.get(self.at) == Some(&b'#') {
                    hashes += 1;
                    self.at += 1;
                }
                if b.get(self.at) != Some(&b'"') {
                    return None;
                }
                self.at += 1;
                loop {
                    if *b.get(self.at)? == b'"'
                        && b[self.at + 1..].iter().take(hashes).filter(|&&h| h == b'#').count() == hashes
                    {
                        self.at += 1 + hashes;
                        break;
                    }
                    self.at += 1;
                }
                Token::Other
            }
            c if c.is_ascii_alphabetic() || c == b'_' => {
                while b.get(self.at).is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_') {
                    self.at += 1;
                }
                Token::Ident(start..self.at)
            }
            _ => Token::Other,
        })
    }

    /// Past the closing quote of a string whose opening quote was just read.
    fn skip_string(&mut self) -> Option<()> {
        loop {
            match *self.bytes.get(self.at)? {
                b'\\' => self.at += 2,
                b'"' => {
                    self.at += 1;
                    return Some(());
                }
                _ => self.at += 1,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_are_found_outside_strings_and_comments() {
        let text = r##"Scene(camera: (), /* objects: [x] */ objects: [
            (name: "a, [b]", shape: Sphere()), // one, two ]
            (name: r#"c"d]"#, shape: Box(min: (0, 0, 0), max: (1, 1, 1))),
            /* nested /* ] */ , */ (shape: Plane()),
        ], lights: [])"##;
        let (list, elements) = objects_list(text).unwrap();
        let found: Vec<&str> = elements.iter().map(|r| &text[r.clone()]).collect();
        assert_eq!(
            found,
            [
                r#"(name: "a, [b]", shape: Sphere())"#,
                r##"// one, two ]
            (name: r#"c"d]"#, shape: Box(min: (0, 0, 0), max: (1, 1, 1)))"##,
                r#"/* nested /* ] */ , */ (shape: Plane())"#,
            ]
        );
        assert!(text[list.end..].trim_start().starts_with("], lights"));
    }
}
