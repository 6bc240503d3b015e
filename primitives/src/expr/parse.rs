//! The expression parser: a tokenizer and a precedence-climbing parser.
//!
//! Grammar (lowest precedence first; `^` and `**` are right-associative and bind tighter than a
//! unary sign, so `-x^2 = −(x²)` and `2^-1 = 0.5`):
//!
//! ```text
//! sum     = product (("+" | "-") product)*
//! product = unary (("*" | "/") unary)*
//! unary   = ("+" | "-") unary | power
//! power   = atom (("^" | "**") unary)?
//! atom    = number | "x" | "y" | "z" | constant | function "(" sum ("," sum)* ")" | "(" sum ")"
//! ```
//!
//! Numbers are decimal with an optional exponent (`2`, `.5`, `1e-3`, `6.02E+23`). Columns in
//! errors count characters from 1.

use super::{Func1, Func2, Node, ParseError};

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Number(f64),
    Name(String),
    Symbol(&'static str),
    End,
}

struct Lexed {
    token: Token,
    column: usize,
}

fn tokenize(text: &str) -> Result<Vec<Lexed>, ParseError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || (c == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit)) {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            // an exponent: e or E, an optional sign, then at least one digit
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    while j < chars.len() && chars[j].is_ascii_digit() {
                        j += 1;
                    }
                    i = j;
                }
            }
            let literal: String = chars[start..i].iter().collect();
            let value = literal.parse::<f64>().map_err(|_| ParseError {
                column,
                message: format!("malformed number `{literal}`"),
            })?;
            if !value.is_finite() {
                // `1e400` rounds to ∞, and `∞·0` is undefined right where the surface lies
                return Err(ParseError {
                    column,
                    message: format!("number `{literal}` is beyond the largest double (about 1.8e308)"),
                });
            }
            out.push(Lexed {
                token: Token::Number(value),
                column,
            });
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push(Lexed {
                token: Token::Name(chars[start..i].iter().collect()),
                column,
            });
        } else {
            let two: String = chars[i..(i + 2).min(chars.len())].iter().collect();
            let symbol = if two == "**" {
                "**"
            } else {
                match c {
                    '+' => "+",
                    '-' => "-",
                    '*' => "*",
                    '/' => "/",
                    '^' => "^",
                    '(' => "(",
                    ')' => ")",
                    ',' => ",",
                    _ => {
                        return Err(ParseError {
                            column,
                            message: format!("unexpected character `{c}`"),
                        })
                    }
                }
            };
            i += symbol.len();
            out.push(Lexed {
                token: Token::Symbol(symbol),
                column,
            });
        }
    }
    out.push(Lexed {
        token: Token::End,
        column: chars.len() + 1,
    });
    Ok(out)
}

/// Names of the one-argument functions, as written.
const FUNCTIONS_1: [(&str, Func1); 18] = [
    ("sqrt", Func1::Sqrt),
    ("exp", Func1::Exp),
    ("ln", Func1::Ln),
    ("log", Func1::Ln),
    ("sin", Func1::Sin),
    ("cos", Func1::Cos),
    ("tan", Func1::Tan),
    ("atan", Func1::Atan),
    ("tanh", Func1::Tanh),
    ("asin", Func1::Asin),
    ("acos", Func1::Acos),
    ("sinh", Func1::Sinh),
    ("cosh", Func1::Cosh),
    ("log10", Func1::Log10),
    ("log2", Func1::Log2),
    ("cbrt", Func1::Cbrt),
    ("abs", Func1::Abs),
    ("sq", Func1::Square),
];

/// Names of the two-argument functions.
const FUNCTIONS_2: [(&str, Func2); 3] = [("min", Func2::Min), ("max", Func2::Max), ("pow", Func2::Pow)];

/// Most nested parentheses, calls and signs (the parser recurses once per level).
const MAX_NESTING: usize = 200;

/// Deepest syntax tree accepted (evaluation walks it recursively, also on worker threads with
/// small stacks); a sum of a thousand terms is still fine.
pub(super) const MAX_DEPTH: usize = 1000;

/// Most operations (nodes of the syntax tree: numbers, variables, operators, calls) accepted.
/// Every evaluation walks them all, and loading alone evaluates Φ at thousands of points, so
/// a limit keeps a huge expression (a balanced tree escapes the depth limit) from running for
/// minutes; a sum of a thousand terms like `(x - 1)^2` is well within it.
pub(super) const MAX_NODES: usize = 20_000;

/// Largest integer exponent magnitude taken as an integer power (exact for any base, repeated
/// squaring); a larger integer constant is a general power (positive base). The interval power
/// widens by `|n| + 1` ulps, one step each, so the bound also bounds that cost.
pub(super) const MAX_INTEGER_POWER: f64 = 1024.0;

/// Whether a constant exponent is evaluated as an integer power.
fn is_integer_power(n: f64) -> bool {
    n.fract() == 0.0 && n.abs() <= MAX_INTEGER_POWER
}

/// Characters of the source shown on each side of an error's column.
const EXCERPT_SIDE: usize = 60;

/// `source` as an error message quotes it: whole when short, otherwise the characters within
/// 60 of `column` (1-based), an ellipsis `…` marking each cut end.
#[must_use]
pub fn excerpt(source: &str, column: usize) -> String {
    let count = source.chars().count();
    if count <= 2 * EXCERPT_SIDE {
        return source.to_string();
    }
    let at = column.saturating_sub(1).min(count);
    let start = at.saturating_sub(EXCERPT_SIDE);
    let end = (at + EXCERPT_SIDE).min(count);
    let mut out = String::new();
    if start > 0 {
        out.push('…');
    }
    out.extend(source.chars().skip(start).take(end - start));
    if end < count {
        out.push('…');
    }
    out
}

struct Parser {
    tokens: Vec<Lexed>,
    at: usize,
    nesting: usize,
}

impl Parser {
    fn peek(&self) -> &Token {
        &self.tokens[self.at].token
    }

    fn column(&self) -> usize {
        self.tokens[self.at].column
    }

    fn error<T>(&self, message: impl Into<String>) -> Result<T, ParseError> {
        Err(ParseError {
            column: self.column(),
            message: message.into(),
        })
    }

    fn eat(&mut self, symbol: &'static str) -> bool {
        if self.peek() == &Token::Symbol(symbol) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn describe(&self) -> String {
        match self.peek() {
            Token::Number(v) => format!("number {v}"),
            Token::Name(n) => format!("`{n}`"),
            Token::Symbol(s) => format!("`{s}`"),
            Token::End => "the end of the expression".into(),
        }
    }

    fn sum(&mut self) -> Result<Node, ParseError> {
        let mut left = self.product()?;
        loop {
            let column = self.column();
            if self.eat("+") {
                left = Node::Add(Box::new(left), Box::new(self.product()?), column);
            } else if self.eat("-") {
                left = Node::Sub(Box::new(left), Box::new(self.product()?), column);
            } else {
                return Ok(left);
            }
        }
    }

    fn product(&mut self) -> Result<Node, ParseError> {
        let mut left = self.unary()?;
        loop {
            let column = self.column();
            if self.eat("*") {
                left = Node::Mul(Box::new(left), Box::new(self.unary()?), column);
            } else if self.eat("/") {
                left = Node::Div(Box::new(left), Box::new(self.unary()?), column);
            } else {
                return Ok(left);
            }
        }
    }

    fn unary(&mut self) -> Result<Node, ParseError> {
        if self.nesting >= MAX_NESTING {
            return self.error(format!("nested more than {MAX_NESTING} levels deep"));
        }
        self.nesting += 1;
        let node = self.unary_inner();
        self.nesting -= 1;
        node
    }

    fn unary_inner(&mut self) -> Result<Node, ParseError> {
        let column = self.column();
        if self.eat("-") {
            Ok(match self.unary()? {
                Node::Const(c) => Node::Const(-c),
                node => Node::Neg(Box::new(node), column),
            })
        } else if self.eat("+") {
            self.unary()
        } else {
            self.power()
        }
    }

    fn power(&mut self) -> Result<Node, ParseError> {
        let base = self.atom()?;
        let column = self.column();
        if self.eat("^") || self.eat("**") {
            let exponent = self.unary()?;
            return Ok(match exponent {
                Node::Const(n) if is_integer_power(n) => Node::PowI(Box::new(base), n as i32, column),
                exponent => Node::Call2(Func2::Pow, Box::new(base), Box::new(exponent), column),
            });
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Node, ParseError> {
        let column = self.column();
        match self.peek().clone() {
            Token::Number(v) => {
                self.at += 1;
                Ok(Node::Const(v))
            }
            Token::Symbol("(") => {
                self.at += 1;
                let inner = self.sum()?;
                if !self.eat(")") {
                    return self.error(format!(
                        "expected `)` to close the `(` at column {column}, found {}",
                        self.describe()
                    ));
                }
                Ok(inner)
            }
            Token::Name(name) => {
                self.at += 1;
                if self.peek() == &Token::Symbol("(") {
                    return self.call(&name, column);
                }
                match name.as_str() {
                    "x" => Ok(Node::Var(0)),
                    "y" => Ok(Node::Var(1)),
                    "z" => Ok(Node::Var(2)),
                    "pi" | "PI" | "π" => Ok(Node::Const(std::f64::consts::PI)),
                    "e" | "E" => Ok(Node::Const(std::f64::consts::E)),
                    "tau" | "TAU" => Ok(Node::Const(std::f64::consts::TAU)),
                    _ if known_function(&name) => Err(ParseError {
                        column,
                        message: format!("function `{name}` needs its arguments in parentheses"),
                    }),
                    _ => Err(ParseError {
                        column,
                        message: format!(
                            "unknown name `{name}`: the variables are x, y, z and the constants pi, e, tau"
                        ),
                    }),
                }
            }
            _ => self.error(format!(
                "expected a number, a variable, a function or `(`, found {}",
                self.describe()
            )),
        }
    }

    fn call(&mut self, name: &str, column: usize) -> Result<Node, ParseError> {
        self.at += 1; // "("
        let mut args = vec![self.sum()?];
        while self.eat(",") {
            args.push(self.sum()?);
        }
        if !self.eat(")") {
            return self.error(format!(
                "expected `,` or `)` in the arguments of `{name}`, found {}",
                self.describe()
            ));
        }
        let arity_error = |n: usize| ParseError {
            column,
            message: format!(
                "`{name}` takes {n} argument{}, got {}",
                if n == 1 { "" } else { "s" },
                args.len()
            ),
        };
        if let Some(&(_, f)) = FUNCTIONS_1.iter().find(|(n, _)| *n == name) {
            if args.len() != 1 {
                return Err(arity_error(1));
            }
            let arg = args.pop().expect("one argument");
            return Ok(match f {
                Func1::Square => Node::PowI(Box::new(arg), 2, column),
                f => Node::Call1(f, Box::new(arg), column),
            });
        }
        if let Some(&(_, f)) = FUNCTIONS_2.iter().find(|(n, _)| *n == name) {
            if args.len() != 2 {
                return Err(arity_error(2));
            }
            let b = args.pop().expect("two arguments");
            let a = args.pop().expect("two arguments");
            return Ok(match (f, b) {
                (Func2::Pow, Node::Const(n)) if is_integer_power(n) => Node::PowI(Box::new(a), n as i32, column),
                (f, b) => Node::Call2(f, Box::new(a), Box::new(b), column),
            });
        }
        Err(ParseError {
            column,
            message: format!(
                "unknown function `{name}`; known: {}",
                FUNCTIONS_1
                    .iter()
                    .map(|(n, _)| *n)
                    .chain(FUNCTIONS_2.iter().map(|(n, _)| *n))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })
    }
}

fn known_function(name: &str) -> bool {
    FUNCTIONS_1.iter().any(|(n, _)| *n == name) || FUNCTIONS_2.iter().any(|(n, _)| *n == name)
}

/// Parses `text` into a tree.
pub(super) fn parse(text: &str) -> Result<Node, ParseError> {
    let mut parser = Parser {
        tokens: tokenize(text)?,
        at: 0,
        nesting: 0,
    };
    if parser.peek() == &Token::End {
        return parser.error("the expression is empty");
    }
    let node = parser.sum()?;
    if parser.peek() != &Token::End {
        return parser.error(format!(
            "expected an operator or the end of the expression, found {}",
            parser.describe()
        ));
    }
    let (depth, nodes) = depth_and_size(&node);
    if depth > MAX_DEPTH {
        return Err(ParseError {
            column: 1,
            message: format!("the expression is {depth} operations deep, more than {MAX_DEPTH}"),
        });
    }
    if nodes > MAX_NODES {
        return Err(ParseError {
            column: 1,
            message: format!(
                "the expression has {nodes} operations, more than {MAX_NODES} (each evaluation walks them all); \
                 simplify it or split the shape into several objects"
            ),
        });
    }
    Ok(node)
}

/// The depth and the node count of a tree, computed without recursion (an explicit stack).
fn depth_and_size(root: &Node) -> (usize, usize) {
    let mut deepest = 0;
    let mut nodes = 0;
    let mut stack = vec![(root, 1usize)];
    while let Some((node, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        nodes += 1;
        match node {
            Node::Const(_) | Node::Var(_) => {}
            Node::Neg(a, _) | Node::PowI(a, _, _) | Node::Call1(_, a, _) => stack.push((a, depth + 1)),
            Node::Add(a, b, _)
            | Node::Sub(a, b, _)
            | Node::Mul(a, b, _)
            | Node::Div(a, b, _)
            | Node::Call2(_, a, b, _) => {
                stack.push((a, depth + 1));
                stack.push((b, depth + 1));
            }
        }
    }
    (deepest, nodes)
}
