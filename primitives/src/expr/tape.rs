//! An expression compiled to a flat instruction tape, and tapes pruned to a region.
//!
//! **Compiling.** The syntax tree becomes a list of instructions in evaluation order (SSA: the
//! instruction at index `i` writes slot `i`, arguments name earlier slots), with identical
//! subexpressions shared (hash-consing) and constant subtrees folded where the fold is exact (the
//! f64 result equals its interval enclosure, so every evaluation type sees the same number as the
//! tree walk). The result is the last slot. One loop ([`Tape::eval`]) runs it in any
//! [`Scalar`], with exactly the operations of the tree walk in [`super::Expr::eval_in`]: a
//! tape's values, enclosures and derivatives equal the tree's, bit for bit (tested).
//!
//! **Pruning** (the technique of libfive and fidget). An interval evaluation over a region
//! (`Tape::eval_choices`) records, for each `min` / `max`, whether one argument is certainly
//! smaller (or larger) than the other everywhere in the region, and for each `abs` whether its
//! argument is certainly positive or negative. `Tape::pruned` then drops the branches that
//! cannot be chosen and turns `abs` into the identity or a negation. Inside the region the pruned
//! tape computes the **same** values: the interval enclosures contain the f64 point values (each
//! directed-rounded operation encloses the nearest-rounded one), so a strict order of the
//! enclosures is the order of the point values, and `min(a, b) = a` exactly where `a < b`. A
//! branch whose enclosure may be undefined (`√` of a negative…) is never dropped, so no domain
//! flag is lost.

use super::lanes::{Lanes, WIDTH};
use super::scalar::{Jet, Scalar};
use super::{Func1, Func2, Node};
use crate::math::enclosure::Enclosure;
use std::collections::HashMap;

/// One instruction; arguments are slot numbers (indices of earlier instructions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Op {
    /// Coordinate 0, 1, 2 (x, y, z).
    Var(u8),
    /// A constant, exact in every evaluation type.
    Const(f64),
    Neg(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    PowI(u32, i32),
    Call1(Func1, u32),
    Call2(Func2, u32, u32),
}

/// Hashable identity of an instruction (the constant by its bits) for sharing.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Key(u8, u64, u32, u32);

impl Op {
    fn key(&self) -> Key {
        match *self {
            Op::Var(i) => Key(0, u64::from(i), 0, 0),
            Op::Const(c) => Key(1, c.to_bits(), 0, 0),
            Op::Neg(a) => Key(2, 0, a, 0),
            Op::Add(a, b) => Key(3, 0, a.min(b), a.max(b)),
            Op::Sub(a, b) => Key(4, 0, a, b),
            Op::Mul(a, b) => Key(5, 0, a.min(b), a.max(b)),
            Op::Div(a, b) => Key(6, 0, a, b),
            Op::PowI(a, n) => Key(7, u64::from(n as u32), a, 0),
            Op::Call1(f, a) => Key(8, f as u64, a, 0),
            Op::Call2(f, a, b) => Key(9, f as u64, a, b),
        }
    }

    /// The argument slots (at most two).
    fn args(&self) -> [Option<u32>; 2] {
        match *self {
            Op::Var(_) | Op::Const(_) => [None, None],
            Op::Neg(a) | Op::PowI(a, _) | Op::Call1(_, a) => [Some(a), None],
            Op::Add(a, b) | Op::Sub(a, b) | Op::Mul(a, b) | Op::Div(a, b) | Op::Call2(_, a, b) => [Some(a), Some(b)],
        }
    }

    fn remapped(&self, map: &[u32]) -> Op {
        let m = |a: u32| map[a as usize];
        match *self {
            Op::Var(i) => Op::Var(i),
            Op::Const(c) => Op::Const(c),
            Op::Neg(a) => Op::Neg(m(a)),
            Op::Add(a, b) => Op::Add(m(a), m(b)),
            Op::Sub(a, b) => Op::Sub(m(a), m(b)),
            Op::Mul(a, b) => Op::Mul(m(a), m(b)),
            Op::Div(a, b) => Op::Div(m(a), m(b)),
            Op::PowI(a, n) => Op::PowI(m(a), n),
            Op::Call1(f, a) => Op::Call1(f, m(a)),
            Op::Call2(f, a, b) => Op::Call2(f, m(a), m(b)),
        }
    }
}

/// What an interval evaluation decided about a `min`, `max` or `abs` over a region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Choice {
    /// Not decided (or not a branching instruction): keep it.
    Both,
    /// `min`/`max`: the first argument everywhere; `abs`: the argument is positive (identity).
    First,
    /// `min`/`max`: the second argument everywhere; `abs`: the argument is negative (negation).
    Second,
}

/// A compiled expression: instructions in evaluation order, the result in the last slot.
#[derive(Clone, Debug, PartialEq)]
pub struct Tape {
    ops: Vec<Op>,
    /// Whether any instruction is a `min`, `max` or `abs` (otherwise pruning never shortens it).
    branches: bool,
}

/// What pruning makes of an instruction: itself, an alias of an earlier slot, a negation.
#[derive(Clone, Copy)]
enum Fate {
    Keep,
    Alias(u32),
    Negate(u32),
}

/// Per-instruction bookkeeping of [`Tape::pruned`], kept by its caller across calls.
#[derive(Default)]
pub(crate) struct Pruning {
    fate: Vec<Fate>,
    live: Vec<bool>,
    map: Vec<u32>,
}

/// Applies a one-argument function in any scalar type (the dispatch of the tree walk and of the
/// tape alike).
#[inline(always)]
pub(crate) fn call1<T: Scalar>(f: Func1, a: T) -> T {
    match f {
        Func1::Sqrt => a.sqrt(),
        Func1::Exp => a.exp(),
        Func1::Ln => a.ln(),
        Func1::Sin => a.sin(),
        Func1::Cos => a.cos(),
        Func1::Tan => a.tan(),
        Func1::Atan => a.atan(),
        Func1::Tanh => a.tanh(),
        Func1::Asin => a.asin(),
        Func1::Acos => a.acos(),
        Func1::Sinh => a.sinh(),
        Func1::Cosh => a.cosh(),
        Func1::Log10 => a.log10(),
        Func1::Log2 => a.log2(),
        Func1::Cbrt => a.cbrt(),
        Func1::Abs => a.abs(),
        Func1::Square => a.powi(2),
    }
}

/// Applies a two-argument function in any scalar type.
#[inline(always)]
pub(crate) fn call2<T: Scalar>(f: Func2, a: T, b: T) -> T {
    match f {
        Func2::Min => a.min(b),
        Func2::Max => a.max(b),
        Func2::Pow => a.pow(b),
    }
}

#[inline(always)]
fn step<T: Scalar>(op: &Op, slots: &[T], vars: &[T; 3]) -> T {
    let s = |a: u32| slots[a as usize];
    match *op {
        Op::Var(i) => vars[i as usize],
        Op::Const(c) => T::constant(c),
        Op::Neg(a) => -s(a),
        Op::Add(a, b) => s(a) + s(b),
        Op::Sub(a, b) => s(a) - s(b),
        Op::Mul(a, b) => s(a) * s(b),
        Op::Div(a, b) => s(a) / s(b),
        Op::PowI(a, n) => s(a).powi(n),
        Op::Call1(f, a) => call1(f, s(a)),
        Op::Call2(f, a, b) => call2(f, s(a), s(b)),
    }
}

struct Compiler {
    ops: Vec<Op>,
    shared: HashMap<Key, u32>,
}

impl Compiler {
    fn push(&mut self, op: Op) -> u32 {
        // fold instructions whose arguments are all constants when the fold is exact
        let args = op.args();
        let constant = |a: Option<u32>| a.is_none_or(|a| matches!(self.ops[a as usize], Op::Const(_)));
        if !matches!(op, Op::Const(_) | Op::Var(_)) && constant(args[0]) && constant(args[1]) {
            let value = |a: Option<u32>| match a.map(|a| self.ops[a as usize]) {
                Some(Op::Const(c)) => c,
                _ => 0.0,
            };
            let (a, b) = (value(args[0]), value(args[1]));
            // the same instruction reading its constants from slots 0 and 1
            let mut rebase = vec![0u32; self.ops.len()];
            if let Some(b) = args[1] {
                rebase[b as usize] = 1;
            }
            let local = op.remapped(&rebase);
            let point = step::<f64>(&local, &[a, b], &[0.0; 3]);
            let (ea, eb) = (Enclosure::point(a), Enclosure::point(b));
            let enclosure = step::<Enclosure>(&local, &[ea, eb], &[Enclosure::point(0.0); 3]);
            if point.is_finite() && !enclosure.undefined() && enclosure.lo == point && enclosure.hi == point {
                return self.push(Op::Const(point));
            }
        }
        let key = op.key();
        if let Some(&slot) = self.shared.get(&key) {
            return slot;
        }
        let slot = self.ops.len() as u32;
        self.ops.push(op);
        self.shared.insert(key, slot);
        slot
    }

    /// Compiles `root` without recursion (trees may be deep): children first, then the node.
    fn compile(&mut self, root: &Node) -> u32 {
        enum Visit<'a> {
            Enter(&'a Node),
            Exit(&'a Node),
        }
        let mut work = vec![Visit::Enter(root)];
        let mut results: Vec<u32> = Vec::new();
        while let Some(item) = work.pop() {
            match item {
                Visit::Enter(node) => {
                    work.push(Visit::Exit(node));
                    match node {
                        Node::Const(_) | Node::Var(_) => {}
                        Node::Neg(a, _) | Node::PowI(a, _, _) | Node::Call1(_, a, _) => work.push(Visit::Enter(a)),
                        Node::Add(a, b, _)
                        | Node::Sub(a, b, _)
                        | Node::Mul(a, b, _)
                        | Node::Div(a, b, _)
                        | Node::Call2(_, a, b, _) => {
                            // b is popped after a: results hold a then b
                            work.push(Visit::Enter(b));
                            work.push(Visit::Enter(a));
                        }
                    }
                }
                Visit::Exit(node) => {
                    let op = match node {
                        Node::Const(c) => Op::Const(*c),
                        Node::Var(i) => Op::Var(*i),
                        Node::Neg(..) | Node::PowI(..) | Node::Call1(..) => {
                            let a = results.pop().expect("argument compiled");
                            match node {
                                Node::Neg(..) => Op::Neg(a),
                                Node::PowI(_, n, _) => Op::PowI(a, *n),
                                Node::Call1(f, _, _) => Op::Call1(*f, a),
                                _ => unreachable!(),
                            }
                        }
                        Node::Add(..) | Node::Sub(..) | Node::Mul(..) | Node::Div(..) | Node::Call2(..) => {
                            let b = results.pop().expect("argument compiled");
                            let a = results.pop().expect("argument compiled");
                            match node {
                                Node::Add(..) => Op::Add(a, b),
                                Node::Sub(..) => Op::Sub(a, b),
                                Node::Mul(..) => Op::Mul(a, b),
                                Node::Div(..) => Op::Div(a, b),
                                Node::Call2(f, ..) => Op::Call2(*f, a, b),
                                _ => unreachable!(),
                            }
                        }
                    };
                    let slot = self.push(op);
                    results.push(slot);
                }
            }
        }
        results.pop().expect("the root compiled")
    }
}

impl Tape {
    /// Compiles a syntax tree.
    pub(crate) fn compile(root: &Node) -> Self {
        let mut compiler = Compiler {
            ops: Vec::new(),
            shared: HashMap::new(),
        };
        let result = compiler.compile(root);
        let mut ops = compiler.ops;
        // the result must be the last slot: a shared or folded root may sit earlier
        if result as usize != ops.len() - 1 {
            let last = ops[result as usize];
            if matches!(last, Op::Const(_) | Op::Var(_)) {
                ops.push(last);
            } else {
                // x + 0 would round differently for -0; min(r, r) is r exactly in every type
                ops.push(Op::Call2(Func2::Min, result, result));
            }
        }
        let tape = Self::from_ops(ops);
        tape.without_dead_code()
    }

    fn from_ops(ops: Vec<Op>) -> Self {
        let branches = ops
            .iter()
            .any(|op| matches!(op, Op::Call2(Func2::Min | Func2::Max, ..) | Op::Call1(Func1::Abs, _)));
        Self { ops, branches }
    }

    /// Number of instructions.
    #[must_use]
    pub fn len(&self) -> usize {
        self.ops.len()
    }

    /// Whether the tape is empty (never: a compiled expression has at least its result).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.ops.is_empty()
    }

    /// Whether pruning can ever shorten the tape (it has a `min`, `max` or `abs`).
    #[must_use]
    pub fn has_branches(&self) -> bool {
        self.branches
    }

    /// The operands' slots of the result where it is a `max` (`Some((true, a, b))`) or a `min`
    /// (`Some((false, a, b))`) of two different slots: the slots of [`Tape::eval`]'s scratch that
    /// hold them after an evaluation.
    #[must_use]
    pub fn result_extremum(&self) -> Option<(bool, usize, usize)> {
        match *self.ops.last()? {
            Op::Call2(Func2::Max, a, b) if a != b => Some((true, a as usize, b as usize)),
            Op::Call2(Func2::Min, a, b) if a != b => Some((false, a as usize, b as usize)),
            _ => None,
        }
    }

    /// Evaluates in any scalar type with `slots` as scratch space (resized as needed); types of
    /// outward-rounded arithmetic ([`Scalar::DIRECTED`]) in the copy compiled for FMA where the
    /// CPU has it (the same results: the fused operation only computes exact rounding errors).
    #[inline]
    pub fn eval<T: Scalar>(&self, vars: [T; 3], slots: &mut Vec<T>) -> T {
        #[cfg(target_arch = "x86_64")]
        if T::DIRECTED && crate::cpu::has_avx2_fma() {
            // SAFETY: the CPU has AVX2 and FMA (checked just above).
            return unsafe { self.eval_fma(vars, slots) };
        }
        self.eval_here(vars, slots)
    }

    /// [`Tape::eval`] compiled for AVX2 and FMA: the generic counterpart of
    /// [`crate::with_fma!`] (whose copies are monomorphic).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eval_fma<T: Scalar>(&self, vars: [T; 3], slots: &mut Vec<T>) -> T {
        self.eval_here(vars, slots)
    }

    #[inline(always)]
    fn eval_here<T: Scalar>(&self, vars: [T; 3], slots: &mut Vec<T>) -> T {
        let n = self.ops.len();
        if slots.len() < n {
            slots.resize(n, vars[0]);
        }
        let slots = &mut slots[..n];
        for (i, op) in self.ops.iter().enumerate() {
            slots[i] = step(op, slots, &vars);
        }
        slots[n - 1]
    }

    /// Φ at a point in f64.
    #[inline]
    pub fn eval_f64(&self, p: [f64; 3], slots: &mut Vec<f64>) -> f64 {
        self.eval(p, slots)
    }

    /// Φ at many points (`values[i]` for `points[i]`), [`WIDTH`] at a time in [`Lanes`]: the
    /// same bits as [`Tape::eval_f64`] at each point, with the instruction loop run once per
    /// `WIDTH` points.
    pub fn eval_points(&self, points: &[[f64; 3]], values: &mut [f64], slots: &mut Vec<Lanes>) {
        self.eval_points_here(points, values, slots);
    }

    #[inline(always)]
    fn eval_points_here(&self, points: &[[f64; 3]], values: &mut [f64], slots: &mut Vec<Lanes>) {
        assert_eq!(points.len(), values.len());
        for (points, values) in points.chunks(WIDTH).zip(values.chunks_mut(WIDTH)) {
            // unused lanes repeat the first point (their values are dropped)
            let coordinate = |axis: usize| Lanes(std::array::from_fn(|i| points.get(i).unwrap_or(&points[0])[axis]));
            let v = self.eval_here([coordinate(0), coordinate(1), coordinate(2)], slots);
            values.copy_from_slice(&v.0[..values.len()]);
        }
    }

    /// An interval evaluation that also records, per instruction, what it decided about each
    /// `min`, `max` and `abs` (see [`Choice`]) into `choices` (resized to the tape's length).
    pub(crate) fn eval_choices(
        &self,
        vars: [Enclosure; 3],
        slots: &mut Vec<Enclosure>,
        choices: &mut Vec<Choice>,
    ) -> Enclosure {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_avx2_fma() {
            // SAFETY: the CPU has AVX2 and FMA (checked just above).
            return unsafe { self.eval_choices_fma(vars, slots, choices) };
        }
        self.eval_choices_here(vars, slots, choices)
    }

    /// [`Tape::eval_choices`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eval_choices_fma(
        &self,
        vars: [Enclosure; 3],
        slots: &mut Vec<Enclosure>,
        choices: &mut Vec<Choice>,
    ) -> Enclosure {
        self.eval_choices_here(vars, slots, choices)
    }

    #[inline(always)]
    fn eval_choices_here(
        &self,
        vars: [Enclosure; 3],
        slots: &mut Vec<Enclosure>,
        choices: &mut Vec<Choice>,
    ) -> Enclosure {
        slots.clear();
        choices.clear();
        choices.resize(self.ops.len(), Choice::Both);
        for (i, op) in self.ops.iter().enumerate() {
            let v = step(op, slots, &vars);
            match *op {
                Op::Call2(f @ (Func2::Min | Func2::Max), a, b) => {
                    let (x, y) = (slots[a as usize], slots[b as usize]);
                    let order = x.certain_order(y);
                    choices[i] = match (f, order) {
                        (Func2::Min, Some(std::cmp::Ordering::Less))
                        | (Func2::Max, Some(std::cmp::Ordering::Greater))
                            if !y.undefined() =>
                        {
                            Choice::First
                        }
                        (Func2::Min, Some(std::cmp::Ordering::Greater))
                        | (Func2::Max, Some(std::cmp::Ordering::Less))
                            if !x.undefined() =>
                        {
                            Choice::Second
                        }
                        _ => Choice::Both,
                    };
                }
                Op::Call1(Func1::Abs, a) => {
                    let x = slots[a as usize];
                    choices[i] = if x.lo > 0.0 {
                        Choice::First
                    } else if x.hi < 0.0 {
                        Choice::Second
                    } else {
                        Choice::Both
                    };
                }
                _ => {}
            }
            slots.push(v);
        }
        *slots.last().expect("a tape has a result")
    }

    /// The tape with the branches `choices` (from [`Tape::eval_choices`] over a region) ruled
    /// out dropped, or `None` when nothing was decided (the tape is already as short);
    /// `scratch` holds the per-instruction bookkeeping.
    pub(crate) fn pruned(&self, choices: &[Choice], scratch: &mut Pruning) -> Option<Self> {
        if !self.branches || choices.iter().all(|c| *c == Choice::Both) {
            return None;
        }
        let n = self.ops.len();
        let Pruning { fate, live, map } = scratch;
        fate.clear();
        fate.resize(n, Fate::Keep);
        live.clear();
        live.resize(n, false);
        live[n - 1] = true;
        for i in (0..n).rev() {
            if !live[i] {
                continue;
            }
            let op = self.ops[i];
            let decided = match (op, choices[i]) {
                (Op::Call2(Func2::Min | Func2::Max, a, _), Choice::First) => Some(Fate::Alias(a)),
                (Op::Call2(Func2::Min | Func2::Max, _, b), Choice::Second) => Some(Fate::Alias(b)),
                (Op::Call1(Func1::Abs, a), Choice::First) => Some(Fate::Alias(a)),
                (Op::Call1(Func1::Abs, a), Choice::Second) => Some(Fate::Negate(a)),
                _ => None,
            };
            match decided {
                Some(f @ (Fate::Alias(a) | Fate::Negate(a))) => {
                    fate[i] = f;
                    live[a as usize] = true;
                }
                _ => {
                    for a in op.args().into_iter().flatten() {
                        live[a as usize] = true;
                    }
                }
            }
        }
        map.clear();
        map.resize(n, u32::MAX);
        let mut ops = Vec::with_capacity(n);
        for i in 0..n {
            if !live[i] {
                continue;
            }
            match fate[i] {
                Fate::Alias(a) => map[i] = map[a as usize],
                Fate::Negate(a) => {
                    map[i] = ops.len() as u32;
                    ops.push(Op::Neg(map[a as usize]));
                }
                Fate::Keep => {
                    map[i] = ops.len() as u32;
                    ops.push(self.ops[i].remapped(map));
                }
            }
        }
        // the result must be the last slot
        let result = map[n - 1];
        if result as usize != ops.len() - 1 {
            let r = ops[result as usize];
            if matches!(r, Op::Const(_) | Op::Var(_)) {
                ops.push(r);
            } else {
                ops.push(Op::Call2(Func2::Min, result, result));
            }
        }
        Some(Self::from_ops(ops))
    }

    /// The tape without instructions the result does not use.
    fn without_dead_code(&self) -> Self {
        let n = self.ops.len();
        let mut live = vec![false; n];
        live[n - 1] = true;
        for i in (0..n).rev() {
            if live[i] {
                for a in self.ops[i].args().into_iter().flatten() {
                    live[a as usize] = true;
                }
            }
        }
        let mut map = vec![u32::MAX; n];
        let mut ops = Vec::with_capacity(n);
        for i in 0..n {
            if live[i] {
                map[i] = ops.len() as u32;
                ops.push(self.ops[i].remapped(&map));
            }
        }
        Self::from_ops(ops)
    }

    /// ∇Φ at a point (forward mode, the three partial derivatives in one pass) with `slots` as
    /// scratch space.
    pub fn gradient(&self, p: [f64; 3], slots: &mut Vec<Jet<f64, [f64; 3]>>) -> [f64; 3] {
        self.eval(Jet::axes(p), slots).slope
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Expr;
    use glam::DVec3;

    const TEXTS: [&str; 7] = [
        "sin(3*x)*cos(2*y) + sin(y)*cos(z) + sin(z)*cos(x)",
        "(x^2 + y^2 + z^2 + 0.5)^2 - 3*(x^2 + y^2)",
        "exp(-4*(x*x + y*y + z*z)) + exp(-4*((x-0.7)^2 + y*y + z*z)) - 0.5",
        "min(sqrt(x*x + y*y + z*z) - 1, max(abs(x), abs(y)) - 0.5) / (1 + z*z)",
        "asin(0.5*x) + acos(0.3*y) + sinh(z) * cosh(x) + log10(2 + y) + log2(3 + x) + cbrt(x*z - 2)",
        "max(abs(sqrt(x^2 + y^2 + z^2) - 0.9) - 0.02, 0.35 - abs(sin(6*x)*cos(6*y) + sin(6*y)*cos(6*z)))",
        "2*3 + pi/3 + x*(1/3) + x*x + x^2 + sq(x) - pow(2, 0.5) * y",
    ];

    fn tape(text: &str) -> (Expr, Tape) {
        let e = Expr::parse(text).unwrap();
        let t = Tape::compile(&e.root);
        (e, t)
    }

    /// The tape computes exactly the tree walk's numbers in f64, intervals and jets.
    #[test]
    fn tapes_equal_the_tree_walk_bit_for_bit() {
        let (lo, hi) = (DVec3::new(-0.3, 0.1, -1.2), DVec3::new(0.9, 0.4, -0.7));
        for text in TEXTS {
            let (e, t) = tape(text);
            let mut s = Vec::new();
            let mut se = Vec::new();
            let mut sj = Vec::new();
            for k in 0..=20 {
                let f = f64::from(k) / 20.0;
                let p = lo + (hi - lo) * DVec3::new(f, (f * 7.0).fract(), (f * 13.0).fract());
                let a = e.eval(p);
                let b = t.eval_f64(p.to_array(), &mut s);
                assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "{text} at {p}: {a} vs {b}"
                );
                let g = t.gradient(p.to_array(), &mut sj);
                assert_eq!(DVec3::from_array(g), e.gradient(p), "{text} at {p}");
                let q = p + DVec3::splat(0.05 * f);
                let vars = [
                    Enclosure::new(p.x, q.x),
                    Enclosure::new(p.y, q.y),
                    Enclosure::new(p.z, q.z),
                ];
                assert_eq!(t.eval(vars, &mut se), e.eval_in(vars), "{text}");
            }
        }
    }

    #[test]
    fn sharing_and_folding_shorten_the_tape() {
        let (_, t) = tape("(x*x + y*y) + (x*x + y*y) + (2 + 3)");
        // x, y, x*x, y*y, sum, sum+sum, 6, +: eight instructions
        assert_eq!(t.len(), 8, "{t:?}");
        // 1/3 is inexact: not folded (its interval is not a point)
        let (_, t) = tape("x * (1/3)");
        assert_eq!(t.len(), 5, "{t:?}");
    }

    /// Pruned over a box, a tape gives the same values at every point of the box, and drops
    /// the branches that cannot be chosen there.
    #[test]
    fn pruned_tapes_agree_inside_their_region() {
        let text = "min(min(sqrt((x-1)^2 + y^2 + z^2) - 0.5, sqrt((x+1)^2 + y^2 + z^2) - 0.5), abs(z - 3) - 0.1)";
        let (e, t) = tape(text);
        let (lo, hi) = (DVec3::new(0.6, -0.3, -0.3), DVec3::new(1.4, 0.3, 0.3));
        let mut slots = Vec::new();
        let mut choices = Vec::new();
        let vars = [
            Enclosure::new(lo.x, hi.x),
            Enclosure::new(lo.y, hi.y),
            Enclosure::new(lo.z, hi.z),
        ];
        let whole = t.eval_choices(vars, &mut slots, &mut choices);
        assert_eq!(whole, e.enclose(lo, hi));
        let p = t
            .pruned(&choices, &mut Pruning::default())
            .expect("the far sphere and the slab are pruned");
        // (x-1)^2 + y^2 + z^2, sqrt, -0.5: x, 1, x-1, ^2, y, ^2, +, z, ^2, +, sqrt, 0.5, -
        assert_eq!(p.len(), 13, "{p:?}");
        let mut s = Vec::new();
        for k in 0..=50 {
            let f = f64::from(k) / 50.0;
            let q = lo + (hi - lo) * DVec3::new(f, (f * 7.0).fract(), (f * 13.0).fract());
            assert_eq!(p.eval_f64(q.to_array(), &mut s).to_bits(), e.eval(q).to_bits());
        }
        // over a box holding both spheres nothing is decided between them
        let wide = [
            Enclosure::new(-2.0, 2.0),
            Enclosure::new(-0.3, 0.3),
            Enclosure::new(-0.3, 0.3),
        ];
        t.eval_choices(wide, &mut slots, &mut choices);
        let q = t.pruned(&choices, &mut Pruning::default()).expect("the slab is pruned");
        assert!(q.len() < t.len(), "{} of {}", q.len(), t.len());
        assert!(q.len() > p.len(), "both spheres stay: {q:?}");
    }

    /// The copy of the evaluators compiled for FMA gives the portable copy's enclosures bit for
    /// bit (values, jets, and the recorded choices), on every test expression over nested boxes.
    #[test]
    fn fma_copy_equals_the_portable_one() {
        for text in TEXTS
            .iter()
            .copied()
            .chain(["min(x, y) * max(z, x*y) - abs(x - 0.25*z)"])
        {
            let (_, t) = tape(text);
            for k in 1..=12 {
                let w = f64::from(k) * 0.11;
                let c = [
                    0.1 * f64::from(k) - 0.4,
                    0.31 - 0.07 * f64::from(k),
                    0.05 * f64::from(k),
                ];
                let vars: [Enclosure; 3] = std::array::from_fn(|a| Enclosure::new(c[a] - w, c[a] + w));
                let (mut s1, mut s2) = (Vec::new(), Vec::new());
                let got = t.eval(vars, &mut s1);
                let plain = t.eval_here(vars, &mut s2);
                assert_eq!(
                    (got.lo.to_bits(), got.hi.to_bits()),
                    (plain.lo.to_bits(), plain.hi.to_bits()),
                    "{text}"
                );
                let jets = [0, 1, 2].map(|a| Jet::new(vars[a], Enclosure::point([0.6, -0.48, 0.64][a])));
                let (mut j1, mut j2) = (Vec::new(), Vec::new());
                let (a, b) = (t.eval(jets, &mut j1), t.eval_here(jets, &mut j2));
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "{text}");
                let (mut c1, mut c2) = (Vec::new(), Vec::new());
                let x = t.eval_choices(vars, &mut s1, &mut c1);
                let y = t.eval_choices_here(vars, &mut s2, &mut c2);
                assert_eq!(format!("{x:?}"), format!("{y:?}"), "{text}");
                assert_eq!(c1, c2, "{text}");
            }
        }
    }

    /// A gradient in one pass gives, component by component, the bits of one-direction jets
    /// along each axis: in f64 at points and in intervals over boxes.
    #[test]
    fn one_pass_gradients_equal_three_directional_passes() {
        for text in TEXTS {
            let (_, t) = tape(text);
            for k in 0..20 {
                let f = f64::from(k);
                let p = [0.37 * f.sin(), 0.21 * f - 1.9, (0.13 * f).cos() - 0.4];
                let got = t.gradient(p, &mut Vec::new());
                let w = 0.01 * (f + 1.0);
                let boxed: [Enclosure; 3] = std::array::from_fn(|a| Enclosure::new(p[a] - w, p[a] + w));
                let enclosed = t.eval(Jet::axes(boxed), &mut Vec::new()).slope;
                for axis in 0..3 {
                    let seed = |a: usize| Jet::new(p[a], if a == axis { 1.0 } else { 0.0 });
                    let one = t.eval([seed(0), seed(1), seed(2)], &mut Vec::new()).slope;
                    assert_eq!(got[axis].to_bits(), one.to_bits(), "{text} at {p:?}, axis {axis}");
                    let seed = |a: usize| Jet::new(boxed[a], Enclosure::point(if a == axis { 1.0 } else { 0.0 }));
                    let one = t.eval([seed(0), seed(1), seed(2)], &mut Vec::new()).slope;
                    assert_eq!(
                        format!("{:?}", enclosed[axis]),
                        format!("{one:?}"),
                        "{text}, axis {axis}"
                    );
                }
            }
        }
    }
}
