//! Expression evaluation and parameter storage (LinuxCNC semantics: docs/gcode.md,
//! "Parameters" and "Expressions").
//!
//! Numbered parameters `#1`–`#5601` are one global table (lengths of the machine's tables in
//! the machine's unit, see [`crate::tables`]); `#1`–`#30` are saved and replaced by the
//! arguments on a subroutine call and restored on return. Named parameters are local to the
//! call (`#<x>`) or global (`#<_x>`); a handful of global names are read-only values the
//! interpreter computes (`#<_x>`, `#<_metric>`, …, see [`Interp::system_param`]).

use std::collections::HashMap;

use super::{Interp, MM_PER_INCH};
use crate::diag::{DiagnosticKind, Span};
use crate::syntax::{
    BinOp, ExprId, ExprKind, Func, MAX_PARAMETER, NameId, ParamRef, parameter_number,
};

/// LinuxCNC's `TOLERANCE_EQUAL` for `EQ` and `NE` (2.9: 0.0001).
const TOLERANCE_EQUAL: f64 = 1e-4;

/// An error while evaluating: where, what kind, what.
#[derive(Debug, Clone)]
pub(super) struct EvalError {
    pub(super) span: Span,
    pub(super) kind: DiagnosticKind,
    pub(super) message: String,
}

/// A resolved assignment target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Target {
    Numbered(u32),
    Named(NameId),
}

/// Parameter storage apart from the call frames' locals.
#[derive(Debug, Clone)]
pub(super) struct Params {
    /// `#0`..=`#5601` (index 0 unused) once a parameter has been written; empty before, when
    /// reads come from `initial` (most programs never write one: no 45 kB table for them).
    numbered: Vec<f64>,
    /// The parameters given at start.
    initial: crate::tables::ParameterTable,
    /// Global named parameters set by the program (`#<_name>`).
    pub(super) globals: HashMap<NameId, f64>,
    /// `#<_value>`: the last subroutine's return value.
    pub(super) value: f64,
    /// `#<_value_returned>`.
    pub(super) value_returned: bool,
}

impl Params {
    pub(super) fn new(table: &crate::tables::ParameterTable) -> Self {
        let mut initial = table.clone();
        // LinuxCNC's parameter files always hold #5220 (the coordinate system); absent, G54.
        initial.values.entry(5220).or_insert(1.0);
        Params {
            numbered: Vec::new(),
            initial,
            globals: HashMap::new(),
            value: 0.0,
            value_returned: false,
        }
    }

    pub(super) fn get(&self, n: u32) -> f64 {
        if self.numbered.is_empty() {
            self.initial.get(n)
        } else {
            self.numbered.get(n as usize).copied().unwrap_or(0.0)
        }
    }

    pub(super) fn set(&mut self, n: u32, v: f64) {
        if n > MAX_PARAMETER {
            return;
        }
        if self.numbered.is_empty() {
            if self.initial.get(n) == v {
                return;
            }
            self.numbered = vec![0.0; MAX_PARAMETER as usize + 1];
            for (&k, &x) in &self.initial.values {
                if let Some(slot) = self.numbered.get_mut(k as usize) {
                    *slot = x;
                }
            }
        }
        if let Some(slot) = self.numbered.get_mut(n as usize) {
            *slot = v;
        }
    }
}

/// Names of the read-only global parameters the interpreter computes.
const SYSTEM_NAMES: &[&str] = &[
    "_x",
    "_y",
    "_z",
    "_a",
    "_b",
    "_c",
    "_abs_x",
    "_abs_y",
    "_abs_z",
    "_abs_a",
    "_abs_b",
    "_abs_c",
    "_metric",
    "_imperial",
    "_absolute",
    "_incremental",
    "_inverse_time",
    "_units_per_minute",
    "_coord_system",
    "_current_tool",
    "_selected_tool",
    "_tool_offset",
    "_feed",
    "_rpm",
    "_motion_mode",
    "_plane",
    "_retract_r_plane",
    "_retract_old_z",
    "_call_level",
    "_value",
    "_value_returned",
    "_line",
];

pub(super) fn is_system_name(name: &str) -> bool {
    SYSTEM_NAMES.contains(&name)
}

fn fail(span: Span, kind: DiagnosticKind, message: String) -> EvalError {
    EvalError {
        span,
        kind,
        message,
    }
}

impl Interp<'_> {
    /// Evaluate expression `id` with the current parameter values.
    pub(super) fn eval(&self, id: ExprId) -> Result<f64, EvalError> {
        let e = self.prog.expr(id);
        let span = e.span;
        let v = match e.kind {
            ExprKind::Number(x) => x,
            ExprKind::Param(r) => self.read_param(r, span)?,
            ExprKind::Neg(a) => -self.eval(a)?,
            ExprKind::Exists(n) => {
                let name = self.name(n);
                let exists = is_system_name(name)
                    || self.params.globals.contains_key(&n)
                    || self.frame().locals.contains_key(&n);
                f64::from(u8::from(exists))
            }
            ExprKind::Atan { y, x } => {
                let (y, x) = (self.eval(y)?, self.eval(x)?);
                y.atan2(x).to_degrees()
            }
            ExprKind::Func { func, arg } => {
                let x = self.eval(arg)?;
                let domain = |ok: bool, what: &str| {
                    if ok {
                        Ok(())
                    } else {
                        Err(fail(
                            span,
                            DiagnosticKind::Arithmetic,
                            format!("{}[{x}]: {what}", func.name()),
                        ))
                    }
                };
                match func {
                    Func::Abs => x.abs(),
                    Func::Acos => {
                        domain((-1.0..=1.0).contains(&x), "the argument must be in -1..1")?;
                        x.acos().to_degrees()
                    }
                    Func::Asin => {
                        domain((-1.0..=1.0).contains(&x), "the argument must be in -1..1")?;
                        x.asin().to_degrees()
                    }
                    Func::Cos => x.to_radians().cos(),
                    Func::Exp => x.exp(),
                    Func::Fix => x.floor(),
                    Func::Fup => x.ceil(),
                    Func::Ln => {
                        domain(x > 0.0, "the argument must be positive")?;
                        x.ln()
                    }
                    // LinuxCNC: (int)(x + 0.5) for x ≥ 0, (int)(x − 0.5) below: halves away
                    // from zero.
                    Func::Round => (x + 0.5f64.copysign(x)).trunc(),
                    Func::Sin => x.to_radians().sin(),
                    Func::Sqrt => {
                        domain(x >= 0.0, "the argument must not be negative")?;
                        x.sqrt()
                    }
                    Func::Tan => x.to_radians().tan(),
                }
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let (a, b) = (self.eval(lhs)?, self.eval(rhs)?);
                binary(op, a, b).map_err(|m| fail(span, DiagnosticKind::Arithmetic, m))?
            }
        };
        if v.is_finite() {
            Ok(v)
        } else {
            Err(fail(
                span,
                DiagnosticKind::Arithmetic,
                "the expression's value is not a finite number".into(),
            ))
        }
    }

    /// Resolve an assignment target (an indirect number is computed now).
    pub(super) fn target(&self, r: ParamRef, span: Span) -> Result<Target, EvalError> {
        match r {
            ParamRef::Numbered(n) => Ok(Target::Numbered(n)),
            ParamRef::Indirect(e) => Ok(Target::Numbered(self.indirect(e, span)?)),
            ParamRef::Named(n) => {
                if is_system_name(self.name(n)) {
                    Err(fail(
                        span,
                        DiagnosticKind::Block,
                        format!("#<{}> is a read-only parameter", self.name(n)),
                    ))
                } else {
                    Ok(Target::Named(n))
                }
            }
        }
    }

    fn indirect(&self, e: ExprId, span: Span) -> Result<u32, EvalError> {
        let x = self.eval(e)?;
        parameter_number(x).ok_or_else(|| {
            fail(
                span,
                DiagnosticKind::ParameterNumber,
                format!("parameter number #{x} is not a whole number in 1..={MAX_PARAMETER}"),
            )
        })
    }

    /// Store a value (the end-of-line step of a block).
    pub(super) fn assign(&mut self, t: Target, v: f64) {
        match t {
            Target::Numbered(n) => self.params.set(n, v),
            Target::Named(n) => {
                if self.name(n).starts_with('_') {
                    self.params.globals.insert(n, v);
                } else {
                    self.frame_mut().locals.insert(n, v);
                }
            }
        }
    }

    fn read_param(&self, r: ParamRef, span: Span) -> Result<f64, EvalError> {
        match r {
            ParamRef::Numbered(n) => Ok(self.read_numbered(n)),
            ParamRef::Indirect(e) => Ok(self.read_numbered(self.indirect(e, span)?)),
            ParamRef::Named(n) => {
                let name = self.name(n);
                if let Some(v) = self.system_param(name) {
                    return Ok(v);
                }
                let found = if name.starts_with('_') {
                    self.params.globals.get(&n)
                } else {
                    self.frame().locals.get(&n)
                };
                found.copied().ok_or_else(|| {
                    fail(
                        span,
                        DiagnosticKind::UndefinedParameter,
                        format!(
                            "parameter #<{name}> is read before it is set{}",
                            if name.starts_with('_') {
                                ""
                            } else {
                                " (names without a leading '_' are local to the subroutine call)"
                            }
                        ),
                    )
                })
            }
        }
    }

    /// A numbered parameter; 5400–5403 and 5420–5425 are computed (current tool and position).
    fn read_numbered(&self, n: u32) -> f64 {
        match n {
            5400 => f64::from(self.st.current_tool),
            5401..=5403 => self.tool_offset_param(n - 5401),
            5420..=5425 => self.program_position_in_units()[(n - 5420) as usize],
            _ => self.params.get(n),
        }
    }

    fn tool_offset_param(&self, axis: u32) -> f64 {
        let unit = self.opts.machine_units.mm();
        self.st.tool_offset[axis as usize] / unit
    }

    /// Current position in program coordinates and program units.
    pub(super) fn program_position_in_units(&self) -> [f64; 6] {
        let p = self.to_program(self.st.pos);
        let k = if self.st.inch { MM_PER_INCH } else { 1.0 };
        std::array::from_fn(|i| if i < 3 { p[i] / k } else { p[i] })
    }

    /// The read-only global parameters (LinuxCNC "predefined named parameters").
    pub(super) fn system_param(&self, name: &str) -> Option<f64> {
        let flag = |b: bool| f64::from(u8::from(b));
        let axis = |i: usize| self.program_position_in_units()[i];
        let k = if self.st.inch { MM_PER_INCH } else { 1.0 };
        let abs = |i: usize| {
            let p = self.st.pos[i];
            if i < 3 { p / k } else { p }
        };
        Some(match name {
            "_x" => axis(0),
            "_y" => axis(1),
            "_z" => axis(2),
            "_a" => axis(3),
            "_b" => axis(4),
            "_c" => axis(5),
            "_abs_x" => abs(0),
            "_abs_y" => abs(1),
            "_abs_z" => abs(2),
            "_abs_a" => abs(3),
            "_abs_b" => abs(4),
            "_abs_c" => abs(5),
            "_metric" => flag(!self.st.inch),
            "_imperial" => flag(self.st.inch),
            "_absolute" => flag(self.st.absolute),
            "_incremental" => flag(!self.st.absolute),
            "_inverse_time" => flag(self.st.inverse_time),
            "_units_per_minute" => flag(!self.st.inverse_time),
            "_coord_system" => coord_system_code(self.st.coord_index),
            "_current_tool" => f64::from(self.st.current_tool),
            "_selected_tool" => f64::from(self.st.selected_tool),
            "_tool_offset" => flag(self.st.tool_offset.iter().any(|&v| v != 0.0)),
            "_feed" => self.st.feed.map_or(0.0, |(mm, _)| mm / k),
            "_rpm" => self.st.spindle_rpm,
            "_motion_mode" => self.st.motion.map_or(800.0, |m| f64::from(m.code10())),
            "_plane" => match self.st.plane {
                super::Plane::XY => 170.0,
                super::Plane::ZX => 180.0,
                super::Plane::YZ => 190.0,
            },
            "_retract_r_plane" => flag(self.st.retract_r_plane),
            "_retract_old_z" => flag(!self.st.retract_r_plane),
            "_call_level" => (self.frames.len() - 1) as f64,
            "_value" => self.params.value,
            "_value_returned" => flag(self.params.value_returned),
            "_line" => f64::from(self.st.line),
            _ => return None,
        })
    }
}

/// The value LinuxCNC gives `#<_coord_system>`: 540, 550, …, 590, 591, 592, 593.
fn coord_system_code(index: usize) -> f64 {
    match index {
        1..=6 => 530.0 + 10.0 * index as f64,
        7 => 591.0,
        8 => 592.0,
        _ => 593.0,
    }
}

/// A binary operation; `Err` names what is undefined.
fn binary(op: BinOp, a: f64, b: f64) -> Result<f64, String> {
    let flag = |x: bool| f64::from(u8::from(x));
    Ok(match op {
        BinOp::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return Err(format!(
                    "{a} ** {b}: a negative number to a non-integer power"
                ));
            }
            a.powf(b)
        }
        BinOp::Mul => a * b,
        BinOp::Div => {
            if b == 0.0 {
                return Err(format!("division by zero ({a} / 0)"));
            }
            a / b
        }
        BinOp::Mod => {
            if b == 0.0 {
                return Err(format!("{a} MOD 0: the divisor is zero"));
            }
            // LinuxCNC: fmod, made non-negative by adding |b|.
            let r = a % b;
            if r < 0.0 { r + b.abs() } else { r }
        }
        BinOp::Add => a + b,
        BinOp::Sub => a - b,
        BinOp::Eq => flag((a - b).abs() < TOLERANCE_EQUAL),
        BinOp::Ne => flag((a - b).abs() >= TOLERANCE_EQUAL),
        BinOp::Gt => flag(a > b),
        BinOp::Ge => flag(a >= b),
        BinOp::Lt => flag(a < b),
        BinOp::Le => flag(a <= b),
        BinOp::And => flag(a != 0.0 && b != 0.0),
        BinOp::Or => flag(a != 0.0 || b != 0.0),
        BinOp::Xor => flag((a != 0.0) != (b != 0.0)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_operations_follow_linuxcnc() {
        // Truth: LinuxCNC Interp::execute_binary1/2 and rs274 (tests/linuxcnc.rs).
        assert_eq!(binary(BinOp::Mod, -7.0, 3.0), Ok(2.0));
        assert_eq!(binary(BinOp::Mod, 7.0, -3.0), Ok(1.0));
        assert_eq!(binary(BinOp::Eq, 1.0, 1.00001), Ok(1.0));
        assert_eq!(binary(BinOp::Ne, 1.0, 1.001), Ok(1.0));
        assert_eq!(binary(BinOp::Xor, 1.0, 3.0), Ok(0.0));
        assert!(
            binary(BinOp::Div, 1.0, 0.0)
                .unwrap_err()
                .contains("division by zero")
        );
        assert!(binary(BinOp::Pow, -2.0, 0.5).is_err());
        assert_eq!(binary(BinOp::Pow, -2.0, 3.0), Ok(-8.0));
    }
}
