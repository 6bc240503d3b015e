//! Φ written once, recorded: a user's generic Φ ([`crate::ScalarField`]) run once in the
//! [`Recorded`] number type, whose operations are written down instead of computed, gives the
//! same syntax tree as the expression text that spells it, so the user's type is compiled,
//! pruned over the octree and traced in packets as a `Function` expression is.
//!
//! What cannot be recorded is refused (the caller keeps evaluating the generic Φ itself):
//! a branch on the values ([`Scalar::certain_order`], [`Scalar::either`]: the recording has no
//! values to branch on), [`Scalar::sign`] (not an operation of expressions), an integer power
//! beyond the expressions' limit, and a tree deeper or larger than an expression may be (the
//! recording is a graph whose shared values the tree repeats; the tape shares them again).
//!
//! The tree evaluates each operation as the generic Φ does it, in the same order with the same
//! [`Scalar`] methods, so its values (and the tape's, which equal the tree's bit for bit) are
//! the generic Φ's, bit for bit, in every number type.

use super::parse::{MAX_DEPTH, MAX_INTEGER_POWER, MAX_NODES};
use super::tape::Op as Step;
use super::{Func1, Func2, Node, Scalar};
use std::cell::RefCell;
use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// The recording in progress on this thread: its steps (instructions as a tape writes them,
/// operands the indices of earlier steps, not yet shared or folded), and whether an operation
/// that cannot be recorded was met.
#[derive(Default)]
struct Recording {
    steps: Vec<Step>,
    refused: bool,
}

thread_local! {
    static RECORDING: RefCell<Recording> = RefCell::default();
}

/// A value of the Φ being recorded: the index of the step that makes it.
#[derive(Clone, Copy, Debug)]
pub struct Recorded(u32);

fn push(step: Step) -> Recorded {
    RECORDING.with(|r| {
        let mut r = r.borrow_mut();
        let index = u32::try_from(r.steps.len()).unwrap_or(u32::MAX);
        if index == u32::MAX {
            r.refused = true;
            return Recorded(0);
        }
        r.steps.push(step);
        Recorded(index)
    })
}

fn refuse() {
    RECORDING.with(|r| r.borrow_mut().refused = true);
}

/// The syntax tree of `phi` run on the coordinates `x, y, z` in [`Recorded`] numbers, or `None`
/// where `phi` does what cannot be recorded (see the module docs). Recordings on one thread
/// nest (`phi` may record another Φ).
pub(crate) fn record(phi: impl FnOnce([Recorded; 3]) -> Recorded) -> Option<Node> {
    /// Puts the outer recording back, also when `phi` panics.
    struct Outer(Option<Recording>);
    impl Drop for Outer {
        fn drop(&mut self) {
            if let Some(outer) = self.0.take() {
                RECORDING.with(|r| *r.borrow_mut() = outer);
            }
        }
    }
    let _outer = Outer(Some(RECORDING.with(|r| std::mem::take(&mut *r.borrow_mut()))));
    let vars = [push(Step::Var(0)), push(Step::Var(1)), push(Step::Var(2))];
    let result = phi(vars);
    let recording = RECORDING.with(|r| std::mem::take(&mut *r.borrow_mut()));
    if recording.refused {
        return None;
    }
    tree(&recording.steps, result.0)
}

/// The tree of step `root`: each use of a step repeats its subtree; `None` beyond the
/// expressions' depth or size.
fn tree(steps: &[Step], root: u32) -> Option<Node> {
    fn build(steps: &[Step], at: u32, depth: usize, size: &mut usize) -> Option<Node> {
        *size += 1;
        if depth > MAX_DEPTH || *size > MAX_NODES {
            return None;
        }
        let mut sub = |i: u32| build(steps, i, depth + 1, size).map(Box::new);
        Some(match steps[at as usize] {
            Step::Const(c) => Node::Const(c),
            Step::Var(i) => Node::Var(i),
            Step::Neg(a) => Node::Neg(sub(a)?, 0),
            Step::Add(a, b) => Node::Add(sub(a)?, sub(b)?, 0),
            Step::Sub(a, b) => Node::Sub(sub(a)?, sub(b)?, 0),
            Step::Mul(a, b) => Node::Mul(sub(a)?, sub(b)?, 0),
            Step::Div(a, b) => Node::Div(sub(a)?, sub(b)?, 0),
            Step::PowI(a, n) => Node::PowI(sub(a)?, n, 0),
            Step::Call1(f, a) => Node::Call1(f, sub(a)?, 0),
            Step::Call2(f, a, b) => Node::Call2(f, sub(a)?, sub(b)?, 0),
        })
    }
    build(steps, root, 1, &mut 0)
}

macro_rules! binary {
    ($trait:ident, $method:ident, $step:ident) => {
        impl $trait for Recorded {
            type Output = Self;
            fn $method(self, other: Self) -> Self {
                push(Step::$step(self.0, other.0))
            }
        }
    };
}
binary!(Add, add, Add);
binary!(Sub, sub, Sub);
binary!(Mul, mul, Mul);
binary!(Div, div, Div);

impl Neg for Recorded {
    type Output = Self;
    fn neg(self) -> Self {
        push(Step::Neg(self.0))
    }
}

macro_rules! calls {
    ($($method:ident => $func:ident),* $(,)?) => {
        $(fn $method(self) -> Self {
            push(Step::Call1(Func1::$func, self.0))
        })*
    };
}

impl Scalar for Recorded {
    fn constant(c: f64) -> Self {
        push(Step::Const(c))
    }

    calls!(sqrt => Sqrt, exp => Exp, ln => Ln, sin => Sin, cos => Cos, tan => Tan, atan => Atan,
        tanh => Tanh, asin => Asin, acos => Acos, sinh => Sinh, cosh => Cosh, log10 => Log10,
        log2 => Log2, cbrt => Cbrt, abs => Abs);

    fn sign(self) -> Self {
        refuse();
        self
    }

    fn powi(self, n: i32) -> Self {
        if f64::from(n).abs() > MAX_INTEGER_POWER {
            refuse();
        }
        push(Step::PowI(self.0, n))
    }

    fn pow(self, y: Self) -> Self {
        push(Step::Call2(Func2::Pow, self.0, y.0))
    }

    fn min(self, y: Self) -> Self {
        push(Step::Call2(Func2::Min, self.0, y.0))
    }

    fn max(self, y: Self) -> Self {
        push(Step::Call2(Func2::Max, self.0, y.0))
    }

    fn certain_order(self, _: Self) -> Option<Ordering> {
        refuse();
        None
    }

    fn either(self, _: Self) -> Self {
        refuse();
        self
    }
}
