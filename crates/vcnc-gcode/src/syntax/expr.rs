//! Expressions, parameter references and their parser (RS274/NGC as LinuxCNC documents it;
//! docs/gcode.md, "Expressions").
//!
//! A *real value* is a number, a bracketed expression `[ … ]`, a parameter `#…`, a function
//! call (`SIN[…]`, `ATAN[…]/[…]`, `EXISTS[#<name>]`) or a signed real value (`-#1`). Inside
//! brackets, real values are joined by binary operators. Precedence, highest first (LinuxCNC's
//! `Interp::precedence`): `**`; `* / MOD`; `+ -`; `EQ NE GT GE LT LE`; `AND OR XOR`. Operators
//! of equal precedence group to the left (`2 ** 3 ** 2` = 64); a sign binds tighter than any
//! operator (`-2 ** 2` = 4).

use std::num::NonZeroU32;

use super::lexer::{Mark, Tok};
use super::{LineParser, MAX_NAME_LEN};
use crate::diag::{DiagnosticKind, Span};

/// Index of an [`Expr`] in [`crate::Program::exprs`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ExprId(NonZeroU32);

impl ExprId {
    /// Position in [`crate::Program::exprs`].
    pub fn index(self) -> usize {
        (self.0.get() - 1) as usize
    }

    pub(crate) fn from_index(i: usize) -> Option<ExprId> {
        u32::try_from(i + 1)
            .ok()
            .and_then(NonZeroU32::new)
            .map(ExprId)
    }
}

/// Index of a name in [`crate::Program::names`] (parameter and O-word names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NameId(pub u32);

impl NameId {
    /// Position in [`crate::Program::names`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// One expression node with its source span.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    /// What the node computes.
    pub kind: ExprKind,
    /// The node's text (for a binary operation: the operator).
    pub span: Span,
}

/// Expression node kinds. Angles are in degrees, as in LinuxCNC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExprKind {
    /// A literal number.
    Number(f64),
    /// The value of a parameter.
    Param(ParamRef),
    /// `-x`.
    Neg(ExprId),
    /// A one-argument function, `NAME[arg]`.
    Func {
        /// Which function.
        func: Func,
        /// Its argument.
        arg: ExprId,
    },
    /// `ATAN[y]/[x]`: the angle of (x, y) in degrees, in (−180, 180].
    Atan {
        /// First argument.
        y: ExprId,
        /// Second argument.
        x: ExprId,
    },
    /// `lhs op rhs`.
    Binary {
        /// The operator.
        op: BinOp,
        /// Left operand.
        lhs: ExprId,
        /// Right operand.
        rhs: ExprId,
    },
    /// `EXISTS[#<name>]`: 1 when the named parameter exists, else 0.
    Exists(NameId),
}

/// A parameter reference.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamRef {
    /// `#n` with a literal whole number n (checked to be in range when parsed).
    Numbered(u32),
    /// `#[expr]` or `##n`: the number is computed when the line runs.
    Indirect(ExprId),
    /// `#<name>`: local to the subroutine call, or global when the name starts with `_`.
    Named(NameId),
}

/// One-argument functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    /// `ABS`.
    Abs,
    /// `ACOS` (degrees).
    Acos,
    /// `ASIN` (degrees).
    Asin,
    /// `COS` (of degrees).
    Cos,
    /// `EXP`.
    Exp,
    /// `FIX`: round down (floor).
    Fix,
    /// `FUP`: round up (ceiling).
    Fup,
    /// `LN`: natural logarithm.
    Ln,
    /// `ROUND`: to the nearest whole number, halves away from zero.
    Round,
    /// `SIN` (of degrees).
    Sin,
    /// `SQRT`.
    Sqrt,
    /// `TAN` (of degrees).
    Tan,
}

impl Func {
    fn from_name(name: &str) -> Option<Func> {
        Some(match name {
            "ABS" => Func::Abs,
            "ACOS" => Func::Acos,
            "ASIN" => Func::Asin,
            "COS" => Func::Cos,
            "EXP" => Func::Exp,
            "FIX" => Func::Fix,
            "FUP" => Func::Fup,
            "LN" => Func::Ln,
            "ROUND" => Func::Round,
            "SIN" => Func::Sin,
            "SQRT" => Func::Sqrt,
            "TAN" => Func::Tan,
            _ => return None,
        })
    }

    /// The name as written in programs.
    pub fn name(self) -> &'static str {
        match self {
            Func::Abs => "ABS",
            Func::Acos => "ACOS",
            Func::Asin => "ASIN",
            Func::Cos => "COS",
            Func::Exp => "EXP",
            Func::Fix => "FIX",
            Func::Fup => "FUP",
            Func::Ln => "LN",
            Func::Round => "ROUND",
            Func::Sin => "SIN",
            Func::Sqrt => "SQRT",
            Func::Tan => "TAN",
        }
    }
}

/// Binary operators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    /// `**`.
    Pow,
    /// `*`.
    Mul,
    /// `/`.
    Div,
    /// `MOD`: the remainder, made non-negative by adding |rhs| (LinuxCNC).
    Mod,
    /// `+`.
    Add,
    /// `-`.
    Sub,
    /// `EQ`: equal within 0.0001 (LinuxCNC's `TOLERANCE_EQUAL`).
    Eq,
    /// `NE`.
    Ne,
    /// `GT`.
    Gt,
    /// `GE`.
    Ge,
    /// `LT`.
    Lt,
    /// `LE`.
    Le,
    /// `AND`.
    And,
    /// `OR`.
    Or,
    /// `XOR`.
    Xor,
}

impl BinOp {
    /// Precedence level, higher binds tighter (LinuxCNC `Interp::precedence`).
    pub fn precedence(self) -> u8 {
        match self {
            BinOp::Pow => 6,
            BinOp::Mul | BinOp::Div | BinOp::Mod => 5,
            BinOp::Add | BinOp::Sub => 4,
            BinOp::Eq | BinOp::Ne | BinOp::Gt | BinOp::Ge | BinOp::Lt | BinOp::Le => 3,
            BinOp::And | BinOp::Or | BinOp::Xor => 2,
        }
    }

    fn from_keyword(name: &str) -> Option<BinOp> {
        Some(match name {
            "MOD" => BinOp::Mod,
            "EQ" => BinOp::Eq,
            "NE" => BinOp::Ne,
            "GT" => BinOp::Gt,
            "GE" => BinOp::Ge,
            "LT" => BinOp::Lt,
            "LE" => BinOp::Le,
            "AND" => BinOp::And,
            "OR" => BinOp::Or,
            "XOR" => BinOp::Xor,
            _ => return None,
        })
    }

    /// The operator as written in programs.
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Pow => "**",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Mod => "MOD",
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Eq => "EQ",
            BinOp::Ne => "NE",
            BinOp::Gt => "GT",
            BinOp::Ge => "GE",
            BinOp::Lt => "LT",
            BinOp::Le => "LE",
            BinOp::And => "AND",
            BinOp::Or => "OR",
            BinOp::Xor => "XOR",
        }
    }
}

/// Deepest nesting of brackets and signs in one value (bounds the parser's recursion).
const MAX_DEPTH: usize = 64;

/// Largest parameter number (LinuxCNC 2.9: `RS274NGC_MAX_PARAMETERS` − 1).
pub const MAX_PARAMETER: u32 = 5601;

/// A parsed real value: a plain number stays a number (no expression node), anything else is
/// an expression.
#[derive(Debug, Clone, Copy)]
pub(super) enum Value {
    Number(f64),
    Expr(ExprId),
}

/// What a value belongs to, for messages (built only when an error is reported).
#[derive(Debug, Clone, Copy)]
pub(super) enum Ctx {
    Word(char),
    Assignment,
    ParameterNumber,
    Expression,
    OArgument,
}

impl std::fmt::Display for Ctx {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Ctx::Word(c) => write!(f, "word '{c}'"),
            Ctx::Assignment => f.write_str("the assignment"),
            Ctx::ParameterNumber => f.write_str("parameter number"),
            Ctx::Expression => f.write_str("the expression"),
            Ctx::OArgument => f.write_str("the O-word argument"),
        }
    }
}

/// A syntax error inside a value: reported, and the rest of the line is abandoned.
#[derive(Debug)]
pub(super) struct Abandon;

impl LineParser<'_, '_> {
    /// Reports a syntax error spanning from `from` to here and abandons the value.
    fn abandon<T>(&mut self, from: Mark, msg: impl Into<String>) -> Result<T, Abandon> {
        let span = self.lx.span_from(from);
        self.error(span, DiagnosticKind::Syntax, msg.into());
        Err(Abandon)
    }

    fn push_expr(&mut self, kind: ExprKind, span: Span) -> Result<ExprId, Abandon> {
        self.builder.push_expr(Expr { kind, span }).ok_or_else(|| {
            self.error(
                span,
                DiagnosticKind::Syntax,
                "too many expression nodes".into(),
            );
            Abandon
        })
    }

    fn as_expr(&mut self, v: Value, span: Span) -> Result<ExprId, Abandon> {
        match v {
            Value::Expr(id) => Ok(id),
            Value::Number(x) => self.push_expr(ExprKind::Number(x), span),
        }
    }

    /// A real value (see the module doc). `what` names the context for messages.
    pub(super) fn real_value(&mut self, depth: usize, what: Ctx) -> Result<(Value, Span), Abandon> {
        if depth > MAX_DEPTH {
            let m = self.lx.mark();
            return self.abandon(
                m,
                format!("expression nested more than {MAX_DEPTH} levels deep"),
            );
        }
        self.lx.skip_ws();
        let m = self.lx.mark();
        match self.lx.peek() {
            Some(b'0'..=b'9' | b'.') => self.number_value(m, what),
            Some(b'+' | b'-') => {
                // A sign before digits is part of the number; before anything else it applies
                // to the following real value.
                let sign = self.lx.peek();
                self.lx.bump();
                if matches!(self.lx.peek_non_ws(), Some(b'0'..=b'9' | b'.')) {
                    self.lx.reset(m);
                    return self.number_value(m, what);
                }
                let (v, vspan) = self.real_value(depth + 1, what)?;
                let span = self.lx.span_from(m);
                if sign == Some(b'+') {
                    return Ok((v, span));
                }
                let arg = self.as_expr(v, vspan)?;
                let id = self.push_expr(ExprKind::Neg(arg), span)?;
                Ok((Value::Expr(id), span))
            }
            Some(b'[') => {
                let id = self.bracketed(depth + 1)?;
                Ok((Value::Expr(id), self.lx.span_from(m)))
            }
            Some(b'#') => {
                self.lx.bump();
                let r = self.param_ref(m, depth + 1)?;
                let span = self.lx.span_from(m);
                let id = self.push_expr(ExprKind::Param(r), span)?;
                Ok((Value::Expr(id), span))
            }
            Some(b) if b.is_ascii_alphabetic() => self.function(m, depth + 1, what),
            Some(b']') => {
                self.lx.bump();
                let span = self.lx.span_from(m);
                self.error(
                    span,
                    DiagnosticKind::UnbalancedBracket,
                    format!("unbalanced ']': {what} needs a value here"),
                );
                Err(Abandon)
            }
            _ => {
                let c = self.lx.bump_char();
                let span = self.lx.span_from(m);
                self.error(
                    span,
                    DiagnosticKind::Syntax,
                    match c {
                        None => format!("{what} needs a value (number, [expression] or #parameter) before the end of the line"),
                        Some(c) => format!("{what} needs a value (number, [expression] or #parameter), found '{c}'"),
                    },
                );
                Err(Abandon)
            }
        }
    }

    fn number_value(&mut self, m: Mark, what: Ctx) -> Result<(Value, Span), Abandon> {
        let (tok, span) = self.lx.number();
        match tok {
            Tok::Number(Some(v), _) => Ok((Value::Number(v), span)),
            Tok::Number(None, raw) => {
                let raw = raw.to_string();
                let span = self.lx.span_from(m);
                self.error(
                    span,
                    DiagnosticKind::Syntax,
                    if raw.bytes().any(|b| b.is_ascii_digit()) {
                        format!("value '{raw}' of {what} is out of range")
                    } else {
                        format!("{what} has a malformed number '{raw}'")
                    },
                );
                Err(Abandon)
            }
            _ => Err(Abandon),
        }
    }

    /// `[ expr ]`; the cursor is on the `[`.
    fn bracketed(&mut self, depth: usize) -> Result<ExprId, Abandon> {
        let open = self.lx.mark();
        self.lx.bump();
        let open_span = self.lx.span_from(open);
        let id = self.binary(0, depth, open_span)?;
        self.lx.skip_ws();
        if self.lx.peek() == Some(b']') {
            self.lx.bump();
            Ok(id)
        } else {
            self.error(
                open_span,
                DiagnosticKind::UnbalancedBracket,
                "unbalanced '[': no matching ']' on this line".into(),
            );
            Err(Abandon)
        }
    }

    /// Operands joined by operators of precedence ≥ `min` (precedence climbing, left
    /// associative), up to a `]` or the end of the line.
    fn binary(&mut self, min: u8, depth: usize, open: Span) -> Result<ExprId, Abandon> {
        if depth > MAX_DEPTH {
            self.error(
                open,
                DiagnosticKind::Syntax,
                format!("expression nested more than {MAX_DEPTH} levels deep"),
            );
            return Err(Abandon);
        }
        let (v, vspan) = self.real_value(depth + 1, Ctx::Expression)?;
        let mut lhs = self.as_expr(v, vspan)?;
        loop {
            self.lx.skip_ws();
            let before = self.lx.mark();
            let Some(op) = self.operator(open)? else {
                break;
            };
            if op.precedence() < min.max(1) {
                self.lx.reset(before);
                break;
            }
            let op_span = self.lx.span_from(before);
            let rhs = self.binary(op.precedence() + 1, depth + 1, open)?;
            lhs = self.push_expr(ExprKind::Binary { op, lhs, rhs }, op_span)?;
        }
        Ok(lhs)
    }

    /// The next binary operator, or `None` at a `]` or the end of the line (which the caller
    /// reports as unbalanced).
    fn operator(&mut self, open: Span) -> Result<Option<BinOp>, Abandon> {
        let m = self.lx.mark();
        let op = match self.lx.peek() {
            None | Some(b']') => return Ok(None),
            Some(b'*') => {
                self.lx.bump();
                if self.lx.peek() == Some(b'*') {
                    self.lx.bump();
                    BinOp::Pow
                } else {
                    BinOp::Mul
                }
            }
            Some(b'/') => {
                self.lx.bump();
                BinOp::Div
            }
            Some(b'+') => {
                self.lx.bump();
                BinOp::Add
            }
            Some(b'-') => {
                self.lx.bump();
                BinOp::Sub
            }
            Some(b) if b.is_ascii_alphabetic() => {
                let (_, name) = self.lx.alpha_run();
                match BinOp::from_keyword(&name) {
                    Some(op) => op,
                    None => {
                        return self.abandon(
                            m,
                            format!(
                                "unknown operator '{name}' in the expression opened at column {}",
                                open.col
                            ),
                        );
                    }
                }
            }
            Some(_) => {
                let c = self.lx.bump_char().unwrap_or('\u{FFFD}');
                return self.abandon(m, format!("expected an operator or ']' in the expression opened at column {}, found '{c}'", open.col));
            }
        };
        Ok(Some(op))
    }

    /// `NAME[…]`, `ATAN[…]/[…]` or `EXISTS[#<name>]`; the cursor is on the first letter.
    fn function(&mut self, m: Mark, depth: usize, what: Ctx) -> Result<(Value, Span), Abandon> {
        let (_, name) = self.lx.alpha_run();
        let name_span = self.lx.span_from(m);
        if self.lx.peek_non_ws() != Some(b'[') {
            self.error(
                name_span,
                DiagnosticKind::Syntax,
                format!(
                    "{what} needs a value, found '{name}' (a function needs its argument in [ ])"
                ),
            );
            return Err(Abandon);
        }
        self.lx.skip_ws();
        let kind = if name == "ATAN" {
            let y = self.bracketed(depth)?;
            self.lx.skip_ws();
            if self.lx.peek() != Some(b'/') {
                return self.abandon(m, "ATAN needs two arguments: ATAN[y]/[x]");
            }
            self.lx.bump();
            self.lx.skip_ws();
            if self.lx.peek() != Some(b'[') {
                return self.abandon(m, "ATAN needs two arguments: ATAN[y]/[x]");
            }
            let x = self.bracketed(depth)?;
            ExprKind::Atan { y, x }
        } else if name == "EXISTS" {
            let open = self.lx.mark();
            self.lx.bump();
            self.lx.skip_ws();
            let hash = self.lx.mark();
            if self.lx.peek() != Some(b'#') {
                return self.abandon(open, "EXISTS needs a named parameter: EXISTS[#<name>]");
            }
            self.lx.bump();
            self.lx.skip_ws();
            if self.lx.peek() != Some(b'<') {
                return self.abandon(hash, "EXISTS needs a named parameter: EXISTS[#<name>]");
            }
            let id = self.name(hash)?;
            self.lx.skip_ws();
            if self.lx.peek() != Some(b']') {
                let span = self.lx.span_from(open);
                self.error(
                    span,
                    DiagnosticKind::UnbalancedBracket,
                    "unbalanced '[': no matching ']' on this line".into(),
                );
                return Err(Abandon);
            }
            self.lx.bump();
            ExprKind::Exists(id)
        } else if let Some(func) = Func::from_name(&name) {
            let arg = self.bracketed(depth)?;
            ExprKind::Func { func, arg }
        } else {
            self.error(
                name_span,
                DiagnosticKind::Syntax,
                format!("unknown function '{name}'"),
            );
            return Err(Abandon);
        };
        let span = self.lx.span_from(m);
        let id = self.push_expr(kind, span)?;
        Ok((Value::Expr(id), span))
    }

    /// After a `#` (at `hash`): `<name>` or a real value giving the number.
    pub(super) fn param_ref(&mut self, hash: Mark, depth: usize) -> Result<ParamRef, Abandon> {
        self.lx.skip_ws();
        if self.lx.peek() == Some(b'<') {
            return self.name(hash).map(ParamRef::Named);
        }
        let (v, vspan) = self.real_value(depth, Ctx::ParameterNumber)?;
        match v {
            Value::Number(x) => {
                let span = self.lx.span_from(hash);
                match parameter_number(x) {
                    Some(n) => Ok(ParamRef::Numbered(n)),
                    None => {
                        self.error(
                            span,
                            DiagnosticKind::ParameterNumber,
                            format!(
                                "parameter number #{x} is not a whole number in 1..={MAX_PARAMETER}"
                            ),
                        );
                        Err(Abandon)
                    }
                }
            }
            Value::Expr(_) => {
                let id = self.as_expr(v, vspan)?;
                Ok(ParamRef::Indirect(id))
            }
        }
    }

    /// `<name>`: blanks removed, lower-cased (LinuxCNC); the cursor is on the `<`.
    pub(super) fn name(&mut self, start: Mark) -> Result<NameId, Abandon> {
        self.lx.bump();
        let mut name = String::new();
        loop {
            match self.lx.peek() {
                None => {
                    return self.abandon(start, "name opened with '<' is never closed with '>'");
                }
                Some(b'>') => {
                    self.lx.bump();
                    break;
                }
                Some(b' ' | b'\t') => self.lx.bump(),
                Some(_) => {
                    let c = self.lx.bump_char().unwrap_or('\u{FFFD}');
                    name.extend(c.to_lowercase());
                }
            }
        }
        let span = self.lx.span_from(start);
        if name.is_empty() || name.len() > MAX_NAME_LEN {
            self.error(
                span,
                DiagnosticKind::Syntax,
                format!("a name needs 1 to {MAX_NAME_LEN} characters between '<' and '>'"),
            );
            return Err(Abandon);
        }
        Ok(self.builder.intern(&name))
    }
}

/// A literal parameter number: a whole number (within LinuxCNC's 0.0001) in 1..=5601.
pub(crate) fn parameter_number(x: f64) -> Option<u32> {
    let r = x.round();
    ((x - r).abs() < 1e-4 && r >= 1.0 && r <= f64::from(MAX_PARAMETER)).then_some(r as u32)
}
