//! Expressions Φ(x, y, z) written in standard notation, evaluated at points, over boxes
//! (interval arithmetic) and along rays with their derivative (forward mode).
//!
//! ```
//! use zeroset_primitives::expr::Expr;
//! use glam::DVec3;
//! let phi = Expr::parse("sqrt(x^2 + y^2 + z^2) - 1e-3").unwrap();
//! assert!((phi.eval(DVec3::new(0.0, 2.0, 0.0)) - 1.999).abs() < 1e-15);
//! let err = Expr::parse("x + * y").unwrap_err();
//! assert_eq!(err.column, 5);
//! ```
//!
//! **Language.** `+ − × ÷` (`+ - * /`), powers `^` or `**` (an integer constant exponent up to
//! 1024 in magnitude is an integer power, defined for any base; any other needs a positive base), unary signs, parentheses; numbers
//! as `2`, `.5`, `1e-3`; variables `x y z`; constants `pi`, `e`, `tau`; functions `sqrt exp ln`
//! (`log` is `ln`) `log10 log2 sin cos tan asin acos atan sinh cosh tanh cbrt abs sq` and
//! `min max pow` of two arguments. See `expr/parse.rs` for the grammar.
//!
//! **Evaluations.** One tree walk generic over [`Scalar`]:
//! - [`Expr::eval`]: `f64` at a point (`NaN`/`±∞` where undefined);
//! - [`Expr::enclose`]: an [`Enclosure`] of Φ over a box, with a flag where an operation may be
//!   outside its domain (`√` of a negative, `ln` of a non-positive, `÷ 0`, a `tan` pole);
//! - [`Expr::enclose_along`]: enclosures of Φ and of `dΦ/dt` on a segment of a ray (interval
//!   forward mode: [`Jet`] of [`Enclosure`]), what the interval root finder needs;
//! - [`Expr::gradient`]: the analytic ∇Φ at a point (forward mode along x, y, z);
//! - [`Expr::domain_error`]: the first operation undefined at a point, with its column.

pub mod cells;
pub(crate) mod distance;
pub mod faces;
pub mod hessian;
pub mod lanes;
mod parse;
pub(crate) mod record;
pub use parse::excerpt;
pub mod scalar;
pub mod tape;

use crate::math::enclosure::Enclosure;
use crate::ray::{Interval, Ray};
use glam::DVec3;
pub use scalar::{Jet, Scalar};
use std::fmt;

/// A syntax error: where (1-based character column) and what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// Column of the offending character or token, counting characters from 1.
    pub column: usize,
    /// What is wrong, in words.
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "column {}: {}", self.column, self.message)
    }
}

impl std::error::Error for ParseError {}

/// A one-argument function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Func1 {
    Sqrt,
    Exp,
    Ln,
    Sin,
    Cos,
    Tan,
    Atan,
    Tanh,
    Asin,
    Acos,
    Sinh,
    Cosh,
    Log10,
    Log2,
    Cbrt,
    Abs,
    /// `sq(x) = x²`, parsed into an integer power.
    Square,
}

/// A two-argument function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Func2 {
    Min,
    Max,
    Pow,
}

/// A node of the syntax tree; operations keep the column they were written at.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Node {
    Const(f64),
    Var(u8),
    Neg(Box<Node>, usize),
    Add(Box<Node>, Box<Node>, usize),
    Sub(Box<Node>, Box<Node>, usize),
    Mul(Box<Node>, Box<Node>, usize),
    Div(Box<Node>, Box<Node>, usize),
    PowI(Box<Node>, i32, usize),
    Call1(Func1, Box<Node>, usize),
    Call2(Func2, Box<Node>, Box<Node>, usize),
}

impl Node {
    /// Moves the children out (replaced by constants) onto `out`.
    fn take_children(&mut self, out: &mut Vec<Node>) {
        let mut take = |child: &mut Box<Node>| out.push(std::mem::replace(&mut **child, Node::Const(0.0)));
        match self {
            Node::Const(_) | Node::Var(_) => {}
            Node::Neg(a, _) | Node::PowI(a, _, _) | Node::Call1(_, a, _) => take(a),
            Node::Add(a, b, _)
            | Node::Sub(a, b, _)
            | Node::Mul(a, b, _)
            | Node::Div(a, b, _)
            | Node::Call2(_, a, b, _) => {
                take(a);
                take(b);
            }
        }
    }
}

/// Dropped without recursion: a rejected expression may be a chain of 10⁵ operations, deeper than
/// a thread's stack allows a recursive drop to go.
impl Drop for Node {
    fn drop(&mut self) {
        let mut pending = Vec::new();
        self.take_children(&mut pending);
        while let Some(mut node) = pending.pop() {
            node.take_children(&mut pending);
        }
    }
}

/// An operation evaluated outside its domain.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DomainError {
    /// Column of the operation in the source.
    pub column: usize,
    /// What happened (`"sqrt of a negative number"`, …).
    pub what: &'static str,
}

impl fmt::Display for DomainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (column {})", self.what, self.column)
    }
}

/// A parsed expression Φ(x, y, z).
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    root: Node,
    source: String,
}

fn walk<T: Scalar>(node: &Node, vars: &[T; 3]) -> T {
    match node {
        Node::Const(c) => T::constant(*c),
        Node::Var(i) => vars[*i as usize],
        Node::Neg(a, _) => -walk(a, vars),
        Node::Add(a, b, _) => walk(a, vars) + walk(b, vars),
        Node::Sub(a, b, _) => walk(a, vars) - walk(b, vars),
        Node::Mul(a, b, _) => walk(a, vars) * walk(b, vars),
        Node::Div(a, b, _) => walk(a, vars) / walk(b, vars),
        Node::PowI(a, n, _) => walk(a, vars).powi(*n),
        Node::Call1(f, a, _) => tape::call1(*f, walk(a, vars)),
        Node::Call2(f, a, b, _) => tape::call2(*f, walk(a, vars), walk(b, vars)),
    }
}

/// Point evaluation that stops at the first operation outside its domain.
fn checked(node: &Node, p: &[f64; 3]) -> Result<f64, DomainError> {
    let fail = |column: usize, what: &'static str| Err(DomainError { column, what });
    Ok(match node {
        Node::Const(c) => *c,
        Node::Var(i) => p[*i as usize],
        Node::Neg(a, _) => -checked(a, p)?,
        Node::Add(a, b, _) => checked(a, p)? + checked(b, p)?,
        Node::Sub(a, b, _) => checked(a, p)? - checked(b, p)?,
        Node::Mul(a, b, _) => checked(a, p)? * checked(b, p)?,
        Node::Div(a, b, column) => {
            let (a, b) = (checked(a, p)?, checked(b, p)?);
            if b == 0.0 {
                return fail(*column, "division by zero");
            }
            a / b
        }
        Node::PowI(a, n, column) => {
            let a = checked(a, p)?;
            if *n < 0 && a == 0.0 {
                return fail(*column, "negative power of zero");
            }
            a.powi(*n)
        }
        Node::Call1(f, a, column) => {
            let a = checked(a, p)?;
            match f {
                Func1::Sqrt if a < 0.0 => return fail(*column, "sqrt of a negative number"),
                Func1::Ln | Func1::Log10 | Func1::Log2 if a <= 0.0 => {
                    return fail(*column, "logarithm of a number ≤ 0")
                }
                Func1::Asin | Func1::Acos if !(-1.0..=1.0).contains(&a) => {
                    return fail(*column, "asin/acos of a number outside [−1, 1]")
                }
                Func1::Tan if a.cos() == 0.0 => return fail(*column, "tan at a pole"),
                _ => tape::call1(*f, a),
            }
        }
        Node::Call2(f, a, b, column) => {
            let (a, b) = (checked(a, p)?, checked(b, p)?);
            match f {
                Func2::Pow if a <= 0.0 && b.fract() == 0.0 => return fail(
                    *column,
                    "pow with a base ≤ 0 and an integer exponent beyond ±1024 (the largest taken as an integer power)",
                ),
                Func2::Pow if a <= 0.0 => return fail(*column, "pow with a base ≤ 0 and a non-integer exponent"),
                Func2::Pow => a.powf(b),
                Func2::Min => a.min(b),
                Func2::Max => a.max(b),
            }
        }
    })
}

/// Enclosures of the coordinates `oᵢ + t·dᵢ`, `t ∈ segment`, intersected with `[lo, hi]`.
pub(crate) fn coordinates_along(ray: &Ray, segment: Interval, lo: DVec3, hi: DVec3) -> Option<[Enclosure; 3]> {
    let t = Enclosure::new(segment.min, segment.max);
    let mut out = [Enclosure::ENTIRE; 3];
    for (axis, slot) in out.iter_mut().enumerate() {
        let c = Enclosure::point(ray.origin[axis]) + t * Enclosure::point(ray.dir[axis]);
        let (a, b) = (c.lo.max(lo[axis]), c.hi.min(hi[axis]));
        if !(a <= b) {
            return None;
        }
        *slot = Enclosure::new(a, b);
    }
    Some(out)
}

/// The jets of the coordinates `c` (enclosures along a ray, from [`coordinates_along`]): each
/// moves with the direction's component per unit of `t`, what an enclosure of `g′(t) = ∇Φ·d`
/// is evaluated from.
pub(crate) fn jets_along(c: [Enclosure; 3], dir: DVec3) -> [Jet<Enclosure>; 3] {
    [
        Jet::new(c[0], Enclosure::point(dir.x)),
        Jet::new(c[1], Enclosure::point(dir.y)),
        Jet::new(c[2], Enclosure::point(dir.z)),
    ]
}

impl Expr {
    /// Parses standard notation (see the module docs); errors carry the column.
    pub fn parse(text: &str) -> Result<Self, ParseError> {
        Ok(Self {
            root: parse::parse(text)?,
            source: text.to_string(),
        })
    }

    /// The expression recorded from a generic Φ ([`record::record`]), named `name` where an
    /// expression names its text.
    pub(crate) fn recorded(root: Node, name: String) -> Self {
        Self { root, source: name }
    }

    /// The expression compiled to an instruction tape ([`tape::Tape`]): the same numbers as
    /// the tree walk, evaluated by one loop.
    #[must_use]
    pub fn compile(&self) -> tape::Tape {
        tape::Tape::compile(&self.root)
    }

    /// The text it was parsed from.
    #[must_use]
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Φ at `p` in f64 (`NaN` or `±∞` where undefined).
    #[must_use]
    pub fn eval(&self, p: DVec3) -> f64 {
        walk(&self.root, &[p.x, p.y, p.z])
    }

    /// Φ in any [`Scalar`] type, with `x, y, z` given in it.
    #[must_use]
    pub fn eval_in<T: Scalar>(&self, vars: [T; 3]) -> T {
        walk(&self.root, &vars)
    }

    /// An enclosure of Φ over the box `[lo, hi]`; [`Enclosure::undefined`] is set where some
    /// operation may be outside its domain within the box.
    #[must_use]
    pub fn enclose(&self, lo: DVec3, hi: DVec3) -> Enclosure {
        self.eval_in([
            Enclosure::new(lo.x, hi.x),
            Enclosure::new(lo.y, hi.y),
            Enclosure::new(lo.z, hi.z),
        ])
    }

    /// Enclosures of `g(t) = Φ(origin + t·dir)` and of `g′(t) = ∇Φ · dir` for all `t` in
    /// `segment`. The coordinates `oᵢ + t·dᵢ` are themselves enclosed (rounding included).
    #[must_use]
    pub fn enclose_along(&self, ray: &Ray, segment: Interval) -> Jet<Enclosure> {
        let everywhere = DVec3::splat(f64::INFINITY);
        self.enclose_along_in(ray, segment, -everywhere, everywhere)
            .expect("every segment meets the whole space")
    }

    /// [`Expr::enclose_along`] for the points of the segment inside the box `[lo, hi]` (each
    /// coordinate enclosure intersected with the box's range); `None` where none is inside.
    /// This is what a function defined only inside its box needs: rounding of the clipped
    /// segment's ends cannot bring in points outside the box (where Φ may be undefined).
    #[must_use]
    pub fn enclose_along_in(&self, ray: &Ray, segment: Interval, lo: DVec3, hi: DVec3) -> Option<Jet<Enclosure>> {
        let c = coordinates_along(ray, segment, lo, hi)?;
        Some(self.eval_in(jets_along(c, ray.dir)))
    }

    /// An enclosure of `g(t) = Φ(origin + t·dir)` for all `t` in `segment` (the value part of
    /// [`Expr::enclose_along`], about a third of its cost).
    #[must_use]
    pub fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Enclosure {
        let everywhere = DVec3::splat(f64::INFINITY);
        self.enclose_value_along_in(ray, segment, -everywhere, everywhere)
            .expect("every segment meets the whole space")
    }

    /// [`Expr::enclose_value_along`] for the points of the segment inside the box `[lo, hi]`.
    #[must_use]
    pub fn enclose_value_along_in(&self, ray: &Ray, segment: Interval, lo: DVec3, hi: DVec3) -> Option<Enclosure> {
        coordinates_along(ray, segment, lo, hi).map(|c| self.eval_in(c))
    }

    /// The analytic gradient ∇Φ at `p` (forward mode, one pass per axis).
    #[must_use]
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        let along = |axis: usize| {
            let mut vars = [Jet::new(p.x, 0.0), Jet::new(p.y, 0.0), Jet::new(p.z, 0.0)];
            vars[axis].slope = 1.0;
            self.eval_in(vars).slope
        };
        DVec3::new(along(0), along(1), along(2))
    }

    /// The first operation (in evaluation order) that is outside its domain at `p`, if any.
    pub fn domain_error(&self, p: DVec3) -> Result<f64, DomainError> {
        checked(&self.root, &[p.x, p.y, p.z])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(text: &str, p: [f64; 3]) -> f64 {
        Expr::parse(text).unwrap().eval(DVec3::from_array(p))
    }

    #[test]
    fn standard_notation_and_precedence() {
        assert_eq!(at("1e-3", [0.0; 3]), 1e-3);
        assert_eq!(at("2.5E+2 + .5", [0.0; 3]), 250.5);
        assert_eq!(at("-x^2", [3.0, 0.0, 0.0]), -9.0);
        assert_eq!(at("2^-1", [0.0; 3]), 0.5);
        assert_eq!(at("2^3^2", [0.0; 3]), 512.0);
        assert_eq!(at("x**2 * y - z / 4", [2.0, 3.0, 8.0]), 10.0);
        assert_eq!(at("min(x, y) + max(x, y) + sq(z)", [1.0, 5.0, 3.0]), 15.0);
        assert_eq!(at("pow(x, 0.5)", [4.0, 0.0, 0.0]), 2.0);
        assert!((at("sin(pi / 2) + ln(e) + cos(0)", [0.0; 3]) - 3.0).abs() < 1e-15);
        assert_eq!(at("abs(-x) - sqrt(16)", [2.0, 0.0, 0.0]), -2.0);
        assert_eq!(at("log10(1000) + log2(8) + cbrt(-27)", [0.0; 3]), 3.0);
        assert!((at("asin(1) + acos(1) - pi/2", [0.0; 3])).abs() < 1e-15);
        assert!((at("cosh(x)^2 - sinh(x)^2", [0.7, 0.0, 0.0]) - 1.0).abs() < 1e-14);
    }

    #[test]
    fn syntax_errors_name_the_column() {
        let cases = [
            ("x + * y", 5, "expected a number"),
            ("sin(x", 6, "expected `,` or `)`"),
            ("(x + 1", 7, "to close the `(` at column 1"),
            ("2x", 2, "expected an operator"),
            ("foo(x)", 1, "unknown function `foo`"),
            ("x + w", 5, "unknown name `w`"),
            ("x # 2", 3, "unexpected character `#`"),
            ("min(x)", 1, "takes 2 arguments, got 1"),
            ("sqrt", 1, "needs its arguments"),
            ("", 1, "empty"),
            ("1..2", 1, "malformed number"),
            ("1e400*x + y", 1, "beyond the largest double"),
        ];
        for (text, column, message) in cases {
            let e = Expr::parse(text).unwrap_err();
            assert_eq!(e.column, column, "{text}: {e}");
            assert!(e.message.contains(message), "{text}: {e}");
        }
    }

    #[test]
    fn integer_powers_above_64_are_integer_powers() {
        for text in ["x^65", "pow(x, 100)", "x**1024", "x^-65"] {
            let e = Expr::parse(text).unwrap();
            assert!(matches!(e.root, Node::PowI(..)), "{text}");
        }
        // defined at negative bases and at 0, with the right values
        let at = |text: &str, x: f64| Expr::parse(text).unwrap().eval(DVec3::new(x, 0.0, 0.0));
        assert_eq!(at("x^65", -1.0), -1.0);
        assert_eq!(at("pow(x, 100)", -2.0), 2f64.powi(100));
        assert_eq!(at("x^100", 0.0), 0.0);
        assert!((at("x^65", 1.01) / 1.01f64.powf(65.0) - 1.0).abs() < 1e-14);
        assert!(Expr::parse("x^65")
            .unwrap()
            .domain_error(DVec3::new(-3.0, 0.0, 0.0))
            .is_ok());
        // an enclosure over a box containing negative bases encloses the values
        let e = Expr::parse("x^65").unwrap();
        let b = e.enclose(DVec3::new(-1.1, 0.0, 0.0), DVec3::new(-0.9, 0.0, 0.0));
        assert!(
            b.lo <= (-1.1f64).powi(65) && b.hi >= (-0.9f64).powi(65) && !b.undefined(),
            "{b:?}"
        );
        // beyond 1024 an integer exponent is a general power, and says so at a base ≤ 0
        let big = Expr::parse("x^2000").unwrap();
        let err = big.domain_error(DVec3::new(-1.0, 0.0, 0.0)).unwrap_err();
        assert!(err.what.contains("integer exponent beyond"), "{err}");
    }

    #[test]
    fn huge_balanced_expressions_are_refused_quickly() {
        // a balanced tree escapes the depth limit (its depth is ~19) but not the size limit
        let mut terms: Vec<String> = (0..131_072).map(|i| format!("x*{i}")).collect();
        while terms.len() > 1 {
            terms = terms.chunks(2).map(|p| format!("({}+{})", p[0], p[1])).collect();
        }
        let text = &terms[0];
        assert!(text.len() > 1_000_000, "{}", text.len());
        let started = std::time::Instant::now();
        let e = Expr::parse(text).unwrap_err();
        assert!(started.elapsed().as_secs_f64() < 2.0, "{:?}", started.elapsed());
        assert!(e.message.contains("operations, more than 20000"), "{e}");
        // a sum of 900 squares (4500 operations) is fine
        let ok = (0..900).map(|i| format!("(x - {i})^2")).collect::<Vec<_>>().join(" + ");
        assert!(Expr::parse(&ok).is_ok());
    }

    #[test]
    fn excerpts_cut_long_sources_around_the_column() {
        assert_eq!(excerpt("x + * y", 5), "x + * y");
        let long = format!("{}@{}", "a".repeat(100_000), "b".repeat(100_000));
        let near = excerpt(&long, 100_001);
        assert_eq!(near, format!("…{}@{}…", "a".repeat(60), "b".repeat(59)));
        assert_eq!(excerpt(&long, 1), format!("{}…", "a".repeat(60)));
        let end = excerpt(&long, 200_002);
        assert!(
            end.starts_with('…') && !end.ends_with('…') && end.chars().count() == 61,
            "{end}"
        );
    }

    #[test]
    fn deep_expressions_are_errors_not_stack_overflows() {
        let nested = format!("{}x{}", "(".repeat(100_000), ")".repeat(100_000));
        let e = Expr::parse(&nested).unwrap_err();
        assert!(e.message.contains("nested more than 200"), "{e}");
        assert_eq!(e.column, 201);
        let signs = format!("{}x", "-".repeat(100_000));
        assert!(Expr::parse(&signs).unwrap_err().message.contains("nested"));
        let long_sum = vec!["x"; 100_000].join(" + ");
        let e = Expr::parse(&long_sum).unwrap_err();
        assert!(e.message.contains("more than 1000"), "{e}");
        // a sum of 500 terms is fine, and evaluates
        let ok = vec!["x"; 500].join(" + ");
        assert_eq!(Expr::parse(&ok).unwrap().eval(DVec3::new(2.0, 0.0, 0.0)), 1000.0);
    }

    #[test]
    fn gradient_is_the_analytic_one() {
        let e = Expr::parse("x^2 * y + sin(z) - sqrt(x*x + y*y) + max(x, -y) + abs(z - 1)").unwrap();
        let p = DVec3::new(0.7, -1.3, 0.4);
        let r = (p.x * p.x + p.y * p.y).sqrt();
        let expected = DVec3::new(
            2.0 * p.x * p.y - p.x / r,
            p.x * p.x - p.y / r - 1.0, // max(x, −y) = −y here
            p.z.cos() - 1.0,
        );
        assert!((e.gradient(p) - expected).length() < 1e-14, "{}", e.gradient(p));
    }

    #[test]
    fn enclosures_contain_point_values() {
        let texts = [
            "sin(3*x)*cos(2*y) + sin(y)*cos(z) + sin(z)*cos(x)",
            "(x^2 + y^2 + z^2 + 0.5)^2 - 3*(x^2 + y^2)",
            "exp(-4*(x*x + y*y + z*z)) + exp(-4*((x-0.7)^2 + y*y + z*z)) - 0.5",
            "min(sqrt(x*x + y*y + z*z) - 1, max(abs(x), abs(y)) - 0.5) / (1 + z*z)",
            "asin(0.5*x) + acos(0.3*y) + sinh(z) * cosh(x) + log10(2 + y) + log2(3 + x) + cbrt(x*z - 2)",
        ];
        let (lo, hi) = (DVec3::new(-0.3, 0.1, -1.2), DVec3::new(0.9, 0.4, -0.7));
        let ray = Ray::new(DVec3::new(-2.0, 0.3, 0.5), DVec3::new(0.8, -0.1, 0.3));
        for text in texts {
            let e = Expr::parse(text).unwrap();
            let b = e.enclose(lo, hi);
            let along = e.enclose_along(&ray, Interval::new(1.0, 2.5));
            for k in 0..=20 {
                let f = f64::from(k) / 20.0;
                let p = lo + (hi - lo) * DVec3::new(f, (f * 7.0).fract(), (f * 13.0).fract());
                assert!(b.contains(e.eval(p)), "{text} at {p}: {b:?}");
                let t = 1.0 + 1.5 * f;
                let q = ray.at(t);
                assert!(along.value.contains(e.eval(q)), "{text} at t = {t}");
                assert!(e.enclose_value_along(&ray, Interval::new(1.0, 2.5)).contains(e.eval(q)));
                let slope = e.gradient(q).dot(ray.dir);
                assert!(
                    along.slope.contains(slope),
                    "{text} slope at t = {t}: {slope} ∉ {:?}",
                    along.slope
                );
            }
        }
    }

    #[test]
    fn domain_errors_are_located() {
        let e = Expr::parse("1 + sqrt(x) + 1/y").unwrap();
        assert_eq!(e.domain_error(DVec3::new(-1.0, 1.0, 0.0)).unwrap_err().column, 5);
        assert_eq!(e.domain_error(DVec3::new(1.0, 0.0, 0.0)).unwrap_err().column, 16);
        assert_eq!(e.domain_error(DVec3::new(4.0, 2.0, 0.0)), Ok(3.5));
        assert!(e.enclose(DVec3::splat(-1.0), DVec3::splat(1.0)).undefined());
        assert!(!e.enclose(DVec3::splat(1.0), DVec3::splat(2.0)).undefined());
    }
}
