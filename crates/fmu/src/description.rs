//! `modelDescription.xml` of a unit, in FMI 2.0 or 3.0.

use crate::units::unit_of;
use crate::variables::{Causality, Start, VarType, Variable};
use crate::FmiVersion;
use std::fmt::Write;

/// What a description says besides its variables.
#[derive(Debug, Clone)]
pub struct Header {
    /// The model's name (`fts-servo stage`).
    pub model_name: String,
    /// The archive's model identifier: the binary's file name without `.so`.
    pub model_identifier: String,
    /// What the unit is, for a reader.
    pub description: String,
    /// The instantiation token (FMI 2's GUID), [`crate::token`].
    pub token: String,
    /// One tick in s: the fixed communication step (and its multiples).
    pub step_s: f64,
    /// The default experiment's stop time in s.
    pub stop_s: f64,
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A real as the XML carries it: the shortest text that reads back to the same bits.
fn real(x: f64) -> String {
    format!("{x:?}")
}

fn causality(c: Causality) -> &'static str {
    match c {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
    }
}

fn variability(v: &Variable) -> &'static str {
    match (v.causality, v.ty) {
        (Causality::Parameter | Causality::CalculatedParameter, _) => "fixed",
        (Causality::Input, VarType::Real) => "continuous",
        _ => "discrete",
    }
}

fn start_text(s: &Start) -> String {
    match s {
        Start::Real(x) => real(*x),
        Start::Integer(n) => n.to_string(),
        Start::Boolean(b) => b.to_string(),
        Start::String(t) => escape(t),
    }
}

/// The units the variables use, once each, as `<UnitDefinitions>`.
fn unit_definitions(vars: &[Variable], time: bool) -> String {
    let mut names: Vec<crate::units::Unit> = Vec::new();
    if time {
        names.extend(unit_of("time_s"));
    }
    for v in vars.iter().filter(|v| v.ty == VarType::Real) {
        if let Some(u) = unit_of(&v.name) {
            if !names.contains(&u) {
                names.push(u);
            }
        }
    }
    let mut out = String::from("  <UnitDefinitions>\n");
    for u in names {
        match u.base {
            Some([kg, m, s, a]) => {
                let mut attrs = String::new();
                for (name, e) in [("kg", kg), ("m", m), ("s", s), ("A", a)] {
                    if e != 0 {
                        let _ = write!(attrs, " {name}=\"{e}\"");
                    }
                }
                let _ = writeln!(
                    out,
                    "    <Unit name=\"{}\"><BaseUnit{attrs}/></Unit>",
                    escape(u.name)
                );
            }
            None => {
                let _ = writeln!(out, "    <Unit name=\"{}\"/>", escape(u.name));
            }
        }
    }
    out.push_str("  </UnitDefinitions>\n");
    out
}

fn range_attrs(v: &Variable) -> String {
    let mut s = String::new();
    if v.ty == VarType::Real {
        if let Some(u) = unit_of(&v.name) {
            let _ = write!(s, " unit=\"{}\"", escape(u.name));
        }
    }
    let number = |x: f64| match v.ty {
        VarType::Integer => format!("{}", x as i64),
        _ => real(x),
    };
    if let Some(x) = v.min {
        let _ = write!(s, " min=\"{}\"", number(x));
    }
    if let Some(x) = v.max {
        let _ = write!(s, " max=\"{}\"", number(x));
    }
    s
}

const LOG_CATEGORIES: &str = "  <LogCategories>\n    <Category name=\"logStatusError\" description=\"Refused calls and their reasons\"/>\n  </LogCategories>\n";

fn default_experiment(h: &Header) -> String {
    format!(
        "  <DefaultExperiment startTime=\"0.0\" stopTime=\"{}\" stepSize=\"{}\"/>\n",
        real(h.stop_s),
        real(h.step_s)
    )
}

fn generation() -> String {
    format!("fts-servo {}", env!("CARGO_PKG_VERSION"))
}

/// The FMI 2.0 description of `vars`.
fn fmi2(h: &Header, vars: &[Variable]) -> String {
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"{}\" guid=\"{}\" description=\"{}\" generationTool=\"{}\" variableNamingConvention=\"structured\" numberOfEventIndicators=\"0\">",
        escape(&h.model_name),
        h.token,
        escape(&h.description),
        generation()
    );
    let _ = writeln!(
        x,
        "  <CoSimulation modelIdentifier=\"{}\" canHandleVariableCommunicationStepSize=\"false\" canInterpolateInputs=\"false\" canRunAsynchronuously=\"false\" canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\" canGetAndSetFMUstate=\"false\" canSerializeFMUstate=\"false\" providesDirectionalDerivative=\"false\"/>",
        h.model_identifier
    );
    x.push_str(&unit_definitions(vars, false));
    x.push_str(LOG_CATEGORIES);
    x.push_str(&default_experiment(h));
    x.push_str("  <ModelVariables>\n");
    for v in vars {
        let ty = match v.ty {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
        };
        let start = v
            .start
            .as_ref()
            .map_or(String::new(), |s| format!(" start=\"{}\"", start_text(s)));
        let _ = writeln!(
            x,
            "    <ScalarVariable name=\"{}\" valueReference=\"{}\" causality=\"{}\" variability=\"{}\" description=\"{}\"><{ty}{start}{}/></ScalarVariable>",
            escape(&v.name),
            v.vr,
            causality(v.causality),
            variability(v),
            escape(&v.description),
            range_attrs(v)
        );
    }
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n");
    // FMI 2 refers to variables by their 1-based index in ModelVariables.
    let index = |vr: u32| {
        1 + vars
            .iter()
            .position(|v| v.vr == vr)
            .expect("an output depends on variables of its unit")
    };
    let outputs: Vec<(usize, &Variable)> = vars
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, v)| (i + 1, v))
        .collect();
    let deps = |v: &Variable| {
        v.depends_on
            .iter()
            .map(|&vr| index(vr).to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    x.push_str("    <Outputs>\n");
    for (i, v) in &outputs {
        let _ = writeln!(
            x,
            "      <Unknown index=\"{i}\" dependencies=\"{}\"/>",
            deps(v)
        );
    }
    x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
    for (i, v) in vars.iter().enumerate() {
        if matches!(
            v.causality,
            Causality::Output | Causality::CalculatedParameter
        ) {
            let _ = writeln!(x, "      <Unknown index=\"{}\"/>", i + 1);
        }
    }
    x.push_str("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n");
    x
}

/// The FMI 3.0 description of `vars`.
fn fmi3(h: &Header, vars: &[Variable]) -> String {
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        "<fmiModelDescription fmiVersion=\"3.0\" modelName=\"{}\" instantiationToken=\"{}\" description=\"{}\" generationTool=\"{}\" variableNamingConvention=\"structured\">",
        escape(&h.model_name),
        h.token,
        escape(&h.description),
        generation()
    );
    let _ = writeln!(
        x,
        "  <CoSimulation modelIdentifier=\"{}\" canHandleVariableCommunicationStepSize=\"false\" fixedInternalStepSize=\"{}\" canGetAndSetFMUState=\"false\" canSerializeFMUState=\"false\" providesDirectionalDerivatives=\"false\" providesAdjointDerivatives=\"false\" providesIntermediateUpdate=\"false\" hasEventMode=\"false\" canReturnEarlyAfterIntermediateUpdate=\"false\"/>",
        h.model_identifier,
        real(h.step_s)
    );
    x.push_str(&unit_definitions(vars, true));
    x.push_str(LOG_CATEGORIES);
    x.push_str(&default_experiment(h));
    x.push_str("  <ModelVariables>\n");
    x.push_str("    <Float64 name=\"time\" valueReference=\"0\" causality=\"independent\" variability=\"continuous\" description=\"Simulation time, s\" unit=\"s\"/>\n");
    for v in vars {
        let ty = match v.ty {
            VarType::Real => "Float64",
            VarType::Integer => "Int32",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
        };
        let head = format!(
            "    <{ty} name=\"{}\" valueReference=\"{}\" causality=\"{}\" variability=\"{}\" description=\"{}\"{}",
            escape(&v.name),
            v.vr,
            causality(v.causality),
            variability(v),
            escape(&v.description),
            range_attrs(v)
        );
        match (&v.start, v.ty) {
            (Some(s), VarType::String) => {
                let _ = writeln!(x, "{head}><Start value=\"{}\"/></{ty}>", start_text(s));
            }
            (Some(s), _) => {
                let _ = writeln!(x, "{head} start=\"{}\"/>", start_text(s));
            }
            (None, _) => {
                let _ = writeln!(x, "{head}/>");
            }
        }
    }
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n");
    let deps = |v: &Variable| {
        v.depends_on
            .iter()
            .map(u32::to_string)
            .collect::<Vec<_>>()
            .join(" ")
    };
    for v in vars.iter().filter(|v| v.causality == Causality::Output) {
        let _ = writeln!(
            x,
            "    <Output valueReference=\"{}\" dependencies=\"{}\"/>",
            v.vr,
            deps(v)
        );
    }
    for v in vars.iter().filter(|v| {
        matches!(
            v.causality,
            Causality::Output | Causality::CalculatedParameter
        )
    }) {
        let _ = writeln!(x, "    <InitialUnknown valueReference=\"{}\"/>", v.vr);
    }
    x.push_str("  </ModelStructure>\n</fmiModelDescription>\n");
    x
}

/// The description of a unit with `vars` in FMI `version`.
pub fn model_description(version: FmiVersion, header: &Header, vars: &[Variable]) -> String {
    match version {
        FmiVersion::V2 => fmi2(header, vars),
        FmiVersion::V3 => fmi3(header, vars),
    }
}
