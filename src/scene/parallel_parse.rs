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

use crate::scene::desc::{ron_options, ObjectDesc, SceneDesc, PARSE_STACK_BYTES};
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
                        // element costs 17 % more instructions, measured); the `]` on a line of
                        // its own, out of a last element's line comment
                        let source = format!("[{}\n]", &text[range]);
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
    let list_start = objects_list_start(bytes)?;
    let mut elements = Vec::new();
    match scan_elements(bytes, list_start, &mut elements) {
        ListScan::Closed(list_end) => Some((list_start..list_end, elements)),
        ListScan::Open(_) | ListScan::Unsure => None,
    }
}

/// The position just after the `[` of the top-level `objects: [`, or `None` if there is none or
/// the lexer is unsure (or `bytes` ends first).
pub(crate) fn objects_list_start(bytes: &[u8]) -> Option<usize> {
    let mut lexer = Lexer { bytes, at: 0 };
    let mut depth = 0usize;
    loop {
        match lexer.token()? {
            Token::Open => depth += 1,
            Token::Close => depth = depth.checked_sub(1)?,
            Token::Ident(range) if depth == 1 && &bytes[range.clone()] == b"objects" => {
                if lexer.token()? != Token::Colon || lexer.token()? != Token::Open || bytes[lexer.at - 1] != b'[' {
                    return None;
                }
                return Some(lexer.at);
            }
            Token::End => return None,
            _ => {}
        }
    }
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

/// How far [`scan_elements`] got.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum ListScan {
    /// The list's closing `]` is at this position.
    Closed(usize),
    /// The bytes end inside the list; the first element not found whole starts here.
    Open(usize),
    /// Unbalanced brackets: the lexer cannot tell.
    Unsure,
}

/// Appends to `elements` the elements of a list whose `[` ends just before `start`: separated by
/// commas at the list's own depth, trimmed of whitespace. Stops at the closing `]` or, where
/// `bytes` is a prefix of the text, before the first element that does not end in it.
pub(crate) fn scan_elements(bytes: &[u8], start: usize, elements: &mut Vec<Range<usize>>) -> ListScan {
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
            b')' | b'}' if depth == 0 => return ListScan::Unsure,
            b')' | b'}' => depth -= 1,
            b']' if depth == 0 => {
                push_trimmed(bytes, element_start..at, elements);
                return ListScan::Closed(at);
            }
            b']' => depth -= 1,
            b',' if depth == 0 => {
                // `[,`, `,,` or a comma after nothing but comments: RON refuses these, and the
                // whole-text parse must say where
                if !push_trimmed(bytes, element_start..at, elements) {
                    return ListScan::Unsure;
                }
                element_start = at + 1;
            }
            b'r' if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_') => {}
            // what follows decides (`//`, `/*`, `r#"`): wait for it
            b'/' | b'r' if at + 1 == bytes.len() => return ListScan::Open(element_start),
            b'"' | b'\'' | b'/' | b'r' => {
                // strings, characters, comments and raw strings: the full lexer skips them
                let mut lexer = Lexer { bytes, at };
                let before = lexer.at;
                match lexer.token() {
                    // the bytes end inside it (or right after a comment)
                    None | Some(Token::End) => return ListScan::Open(element_start),
                    // a lone `/` or an identifier starting with `r`: one byte on
                    Some(Token::Ident(_) | Token::Other) if lexer.at == before + 1 => {}
                    Some(Token::Ident(_) | Token::Other) => {
                        at = lexer.at;
                        continue;
                    }
                    // the lexer skipped a comment and read the next token: rescan from it
                    Some(_) => {
                        at = lexer.at - 1;
                        continue;
                    }
                }
            }
            _ => {}
        }
        at += 1;
    }
    ListScan::Open(element_start)
}

/// Pushes `range` of `bytes` trimmed of ASCII whitespace, unless nothing is left but comments
/// (a trailing comma, a comment after the last element); says whether it pushed. Comments before
/// an element stay inside (the parser skips them).
fn push_trimmed(bytes: &[u8], range: Range<usize>, out: &mut Vec<Range<usize>>) -> bool {
    let slice = &bytes[range.clone()];
    let Some(first) = slice.iter().position(|c| !c.is_ascii_whitespace()) else {
        return false;
    };
    let last = slice.iter().rposition(|c| !c.is_ascii_whitespace()).unwrap_or(first);
    if slice[first] == b'/' {
        let mut lexer = Lexer {
            bytes: &bytes[..range.end],
            at: range.start + first,
        };
        if lexer.token() == Some(Token::End) {
            return false;
        }
    }
    out.push(range.start + first..range.start + last + 1);
    true
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

    #[test]
    fn empty_elements_leave_the_list_to_the_whole_text_parse() {
        for list in ["[(a), , (b)]", "[, (a)]", "[(a), /* c */ , (b)]", "[(a),,]"] {
            let text = format!("Scene(objects: {list})");
            assert_eq!(objects_list(&text), None, "{list}");
            // and RON refuses each of them
            assert!(ron::from_str::<Vec<ron::Value>>(&list.replace("(a)", "1").replace("(b)", "2")).is_err());
        }
        let text = "Scene(objects: [(a), (b), /* end */ ])";
        let (_, elements) = objects_list(text).unwrap();
        assert_eq!(elements.len(), 2);
    }
}
