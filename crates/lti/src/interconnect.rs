//! Interconnection of LTI blocks by named signals.
//!
//! Every block input is a weighted sum of signals: other blocks' outputs or external inputs.
//! With `y = C x + D u_int`, `u_int = K y + E u_ext`, the internal inputs are solved from
//! `(I − K D) u_int = K C x + E u_ext` — so feed-through chains (a white noise passing straight
//! through a biproper filter into a force into an acceleration) are exact — and the result is
//! one state space whose outputs are any named signals.

use crate::state_space::{LtiError, StateSpace};
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::ops::Range;

/// A block: a state space with names for its inputs and outputs.
#[derive(Debug, Clone)]
pub struct NamedBlock {
    /// Block name (for state ranges).
    pub name: String,
    /// Its model.
    pub sys: StateSpace,
    /// One name per input.
    pub inputs: Vec<String>,
    /// One globally unique name per output.
    pub outputs: Vec<String>,
}

impl NamedBlock {
    /// A block from a model and its signal names (counts checked in [`Interconnect::build`]).
    pub fn new(name: &str, sys: StateSpace, inputs: &[&str], outputs: &[&str]) -> Self {
        NamedBlock {
            name: name.to_owned(),
            sys,
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
            outputs: outputs.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// A static gain matrix (no states): `y = D u`.
    pub fn gain(name: &str, d: DMatrix<f64>, inputs: &[&str], outputs: &[&str]) -> Self {
        let (p, m) = d.shape();
        let sys = StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, m),
            c: DMatrix::zeros(p, 0),
            d,
        };
        NamedBlock::new(name, sys, inputs, outputs)
    }
}

/// Interconnection errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConnectError {
    /// A name refers to no signal.
    #[error("unknown signal `{0}`")]
    UnknownSignal(String),
    /// A block's name lists do not match its model.
    #[error("block `{0}`: the number of input/output names does not match the model")]
    NameCount(String),
    /// The feed-through loop `I − K·D` is singular (an algebraic loop with unit gain).
    #[error("algebraic loop: I − K·D is singular")]
    AlgebraicLoop,
    /// An underlying model error.
    #[error(transparent)]
    Lti(#[from] LtiError),
}

/// The result: one model plus where each block's states sit.
#[derive(Debug, Clone)]
pub struct Connected {
    /// The interconnected model; inputs = external inputs in order, outputs = requested signals.
    pub sys: StateSpace,
    /// State index range of each block, by block name.
    pub states: HashMap<String, Range<usize>>,
}

/// A set of blocks and the wiring between them.
#[derive(Debug, Clone, Default)]
pub struct Interconnect {
    blocks: Vec<NamedBlock>,
    external: Vec<String>,
    wires: Vec<(String, String, f64)>,
}

impl Interconnect {
    /// An empty interconnection whose external inputs are `external` (in this order).
    pub fn new(external: &[&str]) -> Self {
        Interconnect {
            external: external.iter().map(|s| s.to_string()).collect(),
            ..Default::default()
        }
    }

    /// Adds a block.
    pub fn block(mut self, block: NamedBlock) -> Self {
        self.blocks.push(block);
        self
    }

    /// Adds `gain × source` to the block input `dest` (inputs sum all their wires).
    pub fn wire(mut self, dest: &str, source: &str, gain: f64) -> Self {
        self.wires.push((dest.to_owned(), source.to_owned(), gain));
        self
    }

    /// Builds the model whose outputs are the signals `outputs` (block outputs or external
    /// inputs).
    pub fn build(&self, outputs: &[&str]) -> Result<Connected, ConnectError> {
        let mut n = 0;
        let (mut m, mut p) = (0, 0);
        let mut states = HashMap::new();
        let mut input_index = HashMap::new();
        let mut output_index = HashMap::new();
        for b in &self.blocks {
            if b.inputs.len() != b.sys.nu() || b.outputs.len() != b.sys.ny() {
                return Err(ConnectError::NameCount(b.name.clone()));
            }
            states.insert(b.name.clone(), n..n + b.sys.nx());
            for name in &b.inputs {
                input_index.insert(name.clone(), m);
                m += 1;
            }
            for name in &b.outputs {
                output_index.insert(name.clone(), p);
                p += 1;
            }
            n += b.sys.nx();
        }
        let mut a = DMatrix::zeros(n, n);
        let mut bb = DMatrix::zeros(n, m);
        let mut c = DMatrix::zeros(p, n);
        let mut d = DMatrix::zeros(p, m);
        let (mut xo, mut uo, mut yo) = (0, 0, 0);
        for b in &self.blocks {
            let (bn, bm, bp) = (b.sys.nx(), b.sys.nu(), b.sys.ny());
            a.view_mut((xo, xo), (bn, bn)).copy_from(&b.sys.a);
            bb.view_mut((xo, uo), (bn, bm)).copy_from(&b.sys.b);
            c.view_mut((yo, xo), (bp, bn)).copy_from(&b.sys.c);
            d.view_mut((yo, uo), (bp, bm)).copy_from(&b.sys.d);
            (xo, uo, yo) = (xo + bn, uo + bm, yo + bp);
        }
        let me = self.external.len();
        let ext_index = |s: &str| self.external.iter().position(|e| e == s);
        let mut k = DMatrix::zeros(m, p);
        let mut e = DMatrix::zeros(m, me);
        for (dest, source, gain) in &self.wires {
            let i = *input_index
                .get(dest)
                .ok_or_else(|| ConnectError::UnknownSignal(dest.clone()))?;
            if let Some(j) = output_index.get(source) {
                k[(i, *j)] += gain;
            } else if let Some(j) = ext_index(source) {
                e[(i, j)] += gain;
            } else {
                return Err(ConnectError::UnknownSignal(source.clone()));
            }
        }
        let f = (DMatrix::identity(m, m) - &k * &d)
            .try_inverse()
            .ok_or(ConnectError::AlgebraicLoop)?;
        let fkc = &f * &k * &c;
        let fe = &f * &e;
        let a_cl = &a + &bb * &fkc;
        let b_cl = &bb * &fe;
        let c_int = &c + &d * &fkc;
        let d_int = &d * &fe;
        let mut c_out = DMatrix::zeros(outputs.len(), n);
        let mut d_out = DMatrix::zeros(outputs.len(), me);
        for (row, name) in outputs.iter().enumerate() {
            if let Some(&j) = output_index.get(*name) {
                c_out.row_mut(row).copy_from(&c_int.row(j));
                d_out.row_mut(row).copy_from(&d_int.row(j));
            } else if let Some(j) = ext_index(name) {
                d_out[(row, j)] = 1.0;
            } else {
                return Err(ConnectError::UnknownSignal(name.to_string()));
            }
        }
        Ok(Connected {
            sys: StateSpace::new(a_cl, b_cl, c_out, d_out)?,
            states,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    fn first_order(pole: f64, gain: f64) -> StateSpace {
        StateSpace::new(
            DMatrix::from_element(1, 1, -pole),
            DMatrix::from_element(1, 1, pole),
            DMatrix::from_element(1, 1, gain),
            DMatrix::zeros(1, 1),
        )
        .unwrap()
    }

    /// Unity negative feedback around G = 10·p/(s + p) gives 10p/(s + 11p).
    #[test]
    fn feedback_loop_matches_closed_form() {
        let p = 100.0;
        let sys = Interconnect::new(&["r"])
            .block(NamedBlock::new("g", first_order(p, 10.0), &["e"], &["y"]))
            .wire("e", "r", 1.0)
            .wire("e", "y", -1.0)
            .build(&["y"])
            .unwrap()
            .sys;
        for f in [1.0, 10.0, 100.0, 1e4] {
            let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            let want = 10.0 * p / (s + 11.0 * p);
            assert!((sys.freq_response_at(f, 0, 0).unwrap() - want).norm() < 1e-12);
        }
    }

    /// A chain with feed-through: static gain 3 then first order: 3·p/(s + p).
    #[test]
    fn feedthrough_chain() {
        let p = 50.0;
        let conn = Interconnect::new(&["u"])
            .block(NamedBlock::gain(
                "k",
                DMatrix::from_element(1, 1, 3.0),
                &["ku"],
                &["kv"],
            ))
            .block(NamedBlock::new("g", first_order(p, 1.0), &["gu"], &["gy"]))
            .wire("ku", "u", 1.0)
            .wire("gu", "kv", 1.0)
            .build(&["gy", "kv", "u"])
            .unwrap();
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * 7.0);
        let g = conn
            .sys
            .freq_response(2.0 * std::f64::consts::PI * 7.0)
            .unwrap();
        assert!((g[(0, 0)] - 3.0 * p / (s + p)).norm() < 1e-12);
        assert!((g[(1, 0)] - 3.0).norm() < 1e-15);
        assert!((g[(2, 0)] - 1.0).norm() < 1e-15);
        assert_eq!(conn.states["g"], 0..1);
    }

    #[test]
    fn unknown_names_and_algebraic_loops_are_errors() {
        let r = Interconnect::new(&["u"])
            .block(NamedBlock::gain(
                "k",
                DMatrix::from_element(1, 1, 1.0),
                &["a"],
                &["b"],
            ))
            .wire("a", "nope", 1.0)
            .build(&["b"]);
        assert_eq!(r.unwrap_err(), ConnectError::UnknownSignal("nope".into()));
        let r = Interconnect::new(&["u"])
            .block(NamedBlock::gain(
                "k",
                DMatrix::from_element(1, 1, 1.0),
                &["a"],
                &["b"],
            ))
            .wire("a", "b", 1.0)
            .build(&["b"]);
        assert_eq!(r.unwrap_err(), ConnectError::AlgebraicLoop);
    }
}
