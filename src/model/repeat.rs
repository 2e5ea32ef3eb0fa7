//! `[[repeat]]`: entries generated from an index, so that a truss of N bays is written
//! once (see docs/model-format.md, "Repetition").
//!
//! Expansion happens after the parameters are resolved (a count may be a parameter that
//! `--set` changes) and before anything else is compiled: the generated nodes, beams,
//! supports, loads, bodies, joints and sensors are appended, in repeat order and then
//! index order, after the entries of the same kind written outside any repeat. Files
//! without `[[repeat]]` are compiled from the parsed spec itself, untouched.
//!
//! Generated entries keep the spans of their template, so an error points at the line of
//! the template; [`Origins::relabel`] turns the field path of a generated entry
//! (`nodes[40].position[1]`) back into the template's (`repeat[0].nodes[1].position[1]`)
//! and names the index values it was generated for.

use std::ops::Range;

use super::error::ModelError;
use super::expr::{self, Scope};
use super::limits::{self, Limits};
use super::spec::*;

type Result<T> = std::result::Result<T, ModelError>;

/// Where each generated entry came from: per kind, for every entry of the expanded spec,
/// `None` (written outside any repeat) or the template path and the index values.
#[derive(Default)]
pub struct Origins {
    kinds: Vec<(&'static str, Vec<Origin>)>,
}

/// Template path and index values of one generated entry (`None`: written by hand).
type Origin = Option<(String, String)>;

impl Origins {
    /// The error of an expanded spec with its field path moved to the template and the
    /// index values named.
    pub fn relabel(&self, mut e: ModelError) -> ModelError {
        let Some(field) = e.field.clone() else {
            return e;
        };
        for (kind, list) in &self.kinds {
            let Some(rest) = field.strip_prefix(kind).and_then(|r| r.strip_prefix('[')) else {
                continue;
            };
            let Some((num, tail)) = rest.split_once(']') else {
                continue;
            };
            let Ok(i) = num.parse::<usize>() else {
                continue;
            };
            if let Some(Some((path, bound))) = list.get(i) {
                e.field = Some(format!("{path}{tail}"));
                e.message += &format!(" (generated for {bound})");
            }
        }
        e
    }
}

/// What one `[[repeat]]` table generated, for `latdyn check`.
#[derive(Clone, Debug, PartialEq)]
pub struct RepeatSummary {
    /// `repeat[0]`, `repeat[0].repeat[1]`
    pub path: String,
    pub index: String,
    pub from: i64,
    pub to: i64,
    /// times the template was generated (its own range times those of enclosing repeats)
    pub iterations: usize,
    /// generated entries by kind: nodes, beams, supports, loads, bodies, joints, sensors
    pub counts: [usize; 7],
}

pub const KINDS: [&str; 7] = [
    "nodes", "beams", "supports", "loads", "bodies", "joints", "sensors",
];

/// The parameters and the values of the enclosing indices.
struct Bound<'a> {
    params: &'a dyn Scope,
    indices: &'a [(String, i64)],
}

impl Scope for Bound<'_> {
    fn value(&self, name: &str) -> Option<f64> {
        match self.indices.iter().rev().find(|(n, _)| n == name) {
            Some((_, v)) => Some(*v as f64),
            None => self.params.value(name),
        }
    }
}

struct Expander<'a> {
    file: &'a str,
    text: &'a str,
    params: &'a dyn Scope,
    out: Spec,
    origins: [Vec<Origin>; 7],
    summary: Vec<RepeatSummary>,
}

/// The spec with every `[[repeat]]` expanded, where each entry came from, and what each
/// repeat generated. `params` are the resolved parameters; a repeat's range is checked
/// against `limits` (with the ranges of the repeats around it) before anything is
/// generated.
pub fn expand(
    spec: &Spec,
    file: &str,
    text: &str,
    params: &dyn Scope,
    lim: &Limits,
) -> Result<(Spec, Origins, Vec<RepeatSummary>)> {
    let mut x = Expander {
        file,
        text,
        params,
        out: Spec {
            repeat: Vec::new(),
            ..spec.clone()
        },
        origins: Default::default(),
        summary: Vec::new(),
    };
    x.origins[0] = vec![None; spec.nodes.len()];
    x.origins[1] = vec![None; spec.beams.len()];
    x.origins[2] = vec![None; spec.supports.len()];
    x.origins[3] = vec![None; spec.loads.len()];
    x.origins[4] = vec![None; spec.bodies.len()];
    x.origins[5] = vec![None; spec.joints.len()];
    x.origins[6] = vec![None; spec.sensors.len()];

    // sizes first: ranges are expressions of the parameters only, so the whole expansion
    // is counted before one entry is made
    let mut total = [0.0f64; 8];
    for (i, r) in spec.repeat.iter().enumerate() {
        x.count(r, &format!("repeat[{i}]"), 1.0, &mut Vec::new(), &mut total)?;
    }
    x.check_size(&total, lim)?;

    for (i, r) in spec.repeat.iter().enumerate() {
        x.generate(r, &format!("repeat[{i}]"), &mut Vec::new())?;
    }
    let Expander {
        out,
        origins,
        summary,
        ..
    } = x;
    let origins = Origins {
        kinds: KINDS.iter().copied().zip(origins).collect(),
    };
    Ok((out, origins, summary))
}

impl Expander<'_> {
    fn err(&self, span: Range<usize>, field: &str, msg: impl std::fmt::Display) -> ModelError {
        ModelError::at(self.file, self.text, span, field, msg)
    }

    /// A whole number from an expression of the parameters.
    fn int(&self, n: &Spanned<Num>, field: &str) -> Result<i64> {
        let v = match n.get_ref() {
            Num::Value(v) => *v,
            Num::Expr(s) => expr::eval_in(s, self.params).map_err(|e| {
                self.err(
                    n.span(),
                    field,
                    format!("{e} (a repeat's range may use the parameters, not the indices)"),
                )
            })?,
        };
        if !v.is_finite() || v.fract() != 0.0 || v.abs() > 1e15 {
            return Err(self.err(
                n.span(),
                field,
                format!("must be a whole number (at most 1e15 in size), is {v}"),
            ));
        }
        Ok(v as i64)
    }

    /// The index name and range of a repeat, checked.
    fn range(
        &self,
        r: &Spanned<RepeatSpec>,
        path: &str,
        outer: &[String],
    ) -> Result<(String, i64, i64)> {
        let rs = r.get_ref();
        let name = rs.index.get_ref().clone();
        let f = format!("{path}.index");
        expr::check_param_name(&name)
            .map_err(|e| self.err(rs.index.span(), &f, e.replace("parameter", "index")))?;
        if self.params.value(&name).is_some() || expr::CONSTANTS.iter().any(|(c, _)| *c == name) {
            return Err(self.err(
                rs.index.span(),
                &f,
                format!("index `{name}` has the name of a parameter or constant"),
            ));
        }
        if outer.contains(&name) {
            return Err(self.err(
                rs.index.span(),
                &f,
                format!("index `{name}` is already the index of an enclosing repeat"),
            ));
        }
        let from = match &rs.from {
            Some(n) => self.int(n, &format!("{path}.from"))?,
            None => 1,
        };
        let to = self.int(&rs.to, &format!("{path}.to"))?;
        if to < from - 1 {
            return Err(self.err(
                rs.to.span(),
                &format!("{path}.to"),
                format!(
                    "is {to}, below from - 1 = {} (to = from - 1 generates nothing; a \
                     larger range runs upwards)",
                    from - 1
                ),
            ));
        }
        Ok((name, from, to))
    }

    /// Adds what `r` (generated `mult` times by the repeats around it) would generate to
    /// `total` (the seven kinds, then iterations).
    fn count(
        &self,
        r: &Spanned<RepeatSpec>,
        path: &str,
        mult: f64,
        outer: &mut Vec<String>,
        total: &mut [f64; 8],
    ) -> Result<()> {
        let (name, from, to) = self.range(r, path, outer)?;
        let rs = r.get_ref();
        let m = mult * (to - from + 1) as f64;
        let sizes = [
            rs.nodes.len(),
            rs.beams.len(),
            rs.supports.len(),
            rs.loads.len(),
            rs.bodies.len(),
            rs.joints.len(),
            rs.sensors.len(),
        ];
        for (t, s) in total.iter_mut().zip(sizes) {
            *t += m * s as f64;
        }
        total[7] += m;
        outer.push(name);
        for (i, inner) in rs.repeat.iter().enumerate() {
            self.count(inner, &format!("{path}.repeat[{i}]"), m, outer, total)?;
        }
        outer.pop();
        Ok(())
    }

    fn check_size(&self, total: &[f64; 8], lim: &Limits) -> Result<()> {
        let fail = |what: String, v: f64, key: &str, limit: u64| {
            Err(ModelError::file(
                self.file,
                Some("repeat".to_string()),
                limits::exceeded(&what, v, key, limit),
            ))
        };
        // each node brings 6 coordinates, each beam at least one element
        if 6.0 * total[0] > lim.dofs as f64 {
            return fail(
                format!(
                    "the coordinates of the nodes the repeats generate ({} nodes × 6)",
                    limits::count(total[0])
                ),
                6.0 * total[0],
                "dofs",
                lim.dofs,
            );
        }
        if total[1] > lim.elements as f64 {
            return fail(
                "the beams the repeats generate (each at least one element)".to_string(),
                total[1],
                "elements",
                lim.elements,
            );
        }
        let all: f64 = total.iter().sum();
        if all > lim.dofs as f64 {
            return fail(
                "the entries and iterations of the repeats".to_string(),
                all,
                "dofs",
                lim.dofs,
            );
        }
        Ok(())
    }

    fn generate(
        &mut self,
        r: &Spanned<RepeatSpec>,
        path: &str,
        indices: &mut Vec<(String, i64)>,
    ) -> Result<()> {
        let outer: Vec<String> = indices.iter().map(|(n, _)| n.clone()).collect();
        let (name, from, to) = self.range(r, path, &outer)?;
        let rs = r.get_ref();
        // the slot is taken before the nested repeats take theirs: summaries in file order
        if !self.summary.iter().any(|s| s.path == path) {
            self.summary.push(RepeatSummary {
                path: path.to_string(),
                index: name.clone(),
                from,
                to,
                iterations: 0,
                counts: [0; 7],
            });
        }
        let mut iterations = 0;
        for v in from..=to {
            iterations += 1;
            indices.push((name.clone(), v));
            let bound = indices
                .iter()
                .map(|(n, v)| format!("{n} = {v}"))
                .collect::<Vec<_>>()
                .join(", ");
            {
                let s = Subst {
                    x: self,
                    scope: Bound {
                        params: self.params,
                        indices: &indices[..],
                    },
                };
                let nodes = each(&rs.nodes, path, "nodes", |e, f| s.node(e, f))?;
                let beams = each(&rs.beams, path, "beams", |e, f| s.beam(e, f))?;
                let supports = each(&rs.supports, path, "supports", |e, f| s.support(e, f))?;
                let loads = each(&rs.loads, path, "loads", |e, f| s.load(e, f))?;
                let bodies = each(&rs.bodies, path, "bodies", |e, f| s.body(e, f))?;
                let joints = each(&rs.joints, path, "joints", |e, f| s.joint(e, f))?;
                let sensors = each(&rs.sensors, path, "sensors", |e, f| s.sensor(e, f))?;
                let o = &mut self.origins;
                let tag = |k: &str, j: usize| Some((format!("{path}.{k}[{j}]"), bound.clone()));
                o[0].extend((0..nodes.len()).map(|j| tag("nodes", j)));
                o[1].extend((0..beams.len()).map(|j| tag("beams", j)));
                o[2].extend((0..supports.len()).map(|j| tag("supports", j)));
                o[3].extend((0..loads.len()).map(|j| tag("loads", j)));
                o[4].extend((0..bodies.len()).map(|j| tag("bodies", j)));
                o[5].extend((0..joints.len()).map(|j| tag("joints", j)));
                o[6].extend((0..sensors.len()).map(|j| tag("sensors", j)));
                self.out.nodes.extend(nodes);
                self.out.beams.extend(beams);
                self.out.supports.extend(supports);
                self.out.loads.extend(loads);
                self.out.bodies.extend(bodies);
                self.out.joints.extend(joints);
                self.out.sensors.extend(sensors);
            }
            for (i, inner) in rs.repeat.iter().enumerate() {
                self.generate(inner, &format!("{path}.repeat[{i}]"), indices)?;
            }
            indices.pop();
        }
        let sizes = [
            rs.nodes.len(),
            rs.beams.len(),
            rs.supports.len(),
            rs.loads.len(),
            rs.bodies.len(),
            rs.joints.len(),
            rs.sensors.len(),
        ];
        let counts = sizes.map(|n| n * iterations);
        if let Some(s) = self.summary.iter_mut().find(|s| s.path == path) {
            s.iterations += iterations;
            for (c, n) in s.counts.iter_mut().zip(counts) {
                *c += n;
            }
        }
        Ok(())
    }
}

fn each<T: Clone>(
    list: &[Spanned<T>],
    path: &str,
    kind: &str,
    mut f: impl FnMut(&T, &str) -> Result<T>,
) -> Result<Vec<Spanned<T>>> {
    list.iter()
        .enumerate()
        .map(|(j, e)| {
            f(e.get_ref(), &format!("{path}.{kind}[{j}]")).map(|v| Spanned::new(e.span(), v))
        })
        .collect()
}

/// Substitution of one iteration's index values into a template entry.
struct Subst<'a, 'b> {
    x: &'a Expander<'b>,
    scope: Bound<'a>,
}

impl Subst<'_, '_> {
    /// `{expr}` replaced by the integer value of `expr` (over parameters and indices).
    fn braces(&self, s: &str, span: Range<usize>, field: &str) -> Result<String> {
        if !s.contains(['{', '}']) {
            return Ok(s.to_string());
        }
        let mut out = String::with_capacity(s.len());
        let mut rest = s;
        while let Some(open) = rest.find(['{', '}']) {
            if rest.as_bytes()[open] == b'}' {
                return Err(self
                    .x
                    .err(span, field, format!("`}}` without `{{` in `{s}`")));
            }
            out.push_str(&rest[..open]);
            let after = &rest[open + 1..];
            let close = after.find('}').ok_or_else(|| {
                self.x
                    .err(span.clone(), field, format!("`{{` without `}}` in `{s}`"))
            })?;
            let inner = &after[..close];
            let v = expr::eval_in(inner, &self.scope).map_err(|e| {
                self.x
                    .err(span.clone(), field, format!("in `{{{inner}}}`: {e}"))
            })?;
            if v.fract() != 0.0 || v.abs() > 1e15 {
                let what = if v.fract() != 0.0 || !v.is_finite() {
                    "not a whole number".to_string()
                } else {
                    "a whole number beyond 1e15, too large for a name".to_string()
                };
                return Err(self
                    .x
                    .err(span, field, format!("`{{{inner}}}` is {v}, {what}")));
            }
            out += &format!("{}", v as i64);
            rest = &after[close + 1..];
        }
        out.push_str(rest);
        Ok(out)
    }

    fn string(&self, s: &Spanned<String>, field: &str) -> Result<Spanned<String>> {
        Ok(Spanned::new(
            s.span(),
            self.braces(s.get_ref(), s.span(), field)?,
        ))
    }

    fn opt_string(
        &self,
        s: &Option<Spanned<String>>,
        field: &str,
    ) -> Result<Option<Spanned<String>>> {
        s.as_ref().map(|s| self.string(s, field)).transpose()
    }

    /// Braces first, then every index name used as a variable becomes its value.
    fn expr_text(&self, s: &str, span: Range<usize>, field: &str) -> Result<String> {
        let s = self.braces(s, span, field)?;
        Ok(replace_idents(&s, self.scope.indices))
    }

    fn num_only(&self, n: &Num, span: Range<usize>, field: &str) -> Result<Num> {
        Ok(match n {
            Num::Value(v) => Num::Value(*v),
            Num::Expr(s) => Num::Expr(self.expr_text(s, span, field)?),
        })
    }

    fn num(&self, n: &Spanned<Num>, field: &str) -> Result<Spanned<Num>> {
        Ok(Spanned::new(
            n.span(),
            self.num_only(n.get_ref(), n.span(), field)?,
        ))
    }

    fn opt_num(&self, n: &Option<Spanned<Num>>, field: &str) -> Result<Option<Spanned<Num>>> {
        n.as_ref().map(|n| self.num(n, field)).transpose()
    }

    fn vector(&self, v: &Spanned<Vector>, field: &str) -> Result<Spanned<Vector>> {
        let items = v
            .get_ref()
            .iter()
            .enumerate()
            .map(|(k, x)| self.num(x, &format!("{field}[{k}]")))
            .collect::<Result<Vector>>()?;
        Ok(Spanned::new(v.span(), items))
    }

    fn opt_vector(
        &self,
        v: &Option<Spanned<Vector>>,
        field: &str,
    ) -> Result<Option<Spanned<Vector>>> {
        v.as_ref().map(|v| self.vector(v, field)).transpose()
    }

    fn num_or_vec(&self, n: &Spanned<NumOrVec>, field: &str) -> Result<Spanned<NumOrVec>> {
        let v = match n.get_ref() {
            NumOrVec::Num(x) => NumOrVec::Num(self.num_only(x, n.span(), field)?),
            NumOrVec::Vec(items) => NumOrVec::Vec(
                items
                    .iter()
                    .enumerate()
                    .map(|(k, x)| self.num(x, &format!("{field}[{k}]")))
                    .collect::<Result<Vector>>()?,
            ),
        };
        Ok(Spanned::new(n.span(), v))
    }

    fn node(&self, n: &NodeSpec, f: &str) -> Result<NodeSpec> {
        Ok(NodeSpec {
            name: self.string(&n.name, &format!("{f}.name"))?,
            position: self.vector(&n.position, &format!("{f}.position"))?,
        })
    }

    fn beam(&self, b: &BeamSpec, f: &str) -> Result<BeamSpec> {
        Ok(BeamSpec {
            name: self.string(&b.name, &format!("{f}.name"))?,
            from: self.string(&b.from, &format!("{f}.from"))?,
            to: self.string(&b.to, &format!("{f}.to"))?,
            elements: self.num(&b.elements, &format!("{f}.elements"))?,
            section: self.string(&b.section, &format!("{f}.section"))?,
            orientation: self.opt_vector(&b.orientation, &format!("{f}.orientation"))?,
            arc_center: self.opt_vector(&b.arc_center, &format!("{f}.arc_center"))?,
        })
    }

    fn support(&self, s: &SupportSpec, f: &str) -> Result<SupportSpec> {
        Ok(SupportSpec {
            node: self.string(&s.node, &format!("{f}.node"))?,
            kind: s.kind.clone(),
        })
    }

    fn load(&self, l: &LoadSpec, f: &str) -> Result<LoadSpec> {
        Ok(LoadSpec {
            node: self.string(&l.node, &format!("{f}.node"))?,
            force: self.opt_vector(&l.force, &format!("{f}.force"))?,
            moment: self.opt_vector(&l.moment, &format!("{f}.moment"))?,
            scale: self.opt_num(&l.scale, &format!("{f}.scale"))?,
            follower: l.follower.clone(),
        })
    }

    fn body(&self, b: &BodySpec, f: &str) -> Result<BodySpec> {
        let axes = match &b.axes {
            None => None,
            Some(a) => Some(Spanned::new(
                a.span(),
                a.get_ref()
                    .iter()
                    .enumerate()
                    .map(|(k, v)| self.vector(v, &format!("{f}.axes[{k}]")))
                    .collect::<Result<Vec<_>>>()?,
            )),
        };
        let inertia = match &b.inertia {
            None => None,
            Some(a) => Some(Spanned::new(
                a.span(),
                a.get_ref()
                    .iter()
                    .enumerate()
                    .map(|(k, v)| self.num_or_vec(v, &format!("{f}.inertia[{k}]")))
                    .collect::<Result<Vec<_>>>()?,
            )),
        };
        let dofs = b
            .dofs
            .iter()
            .enumerate()
            .map(|(k, d)| {
                let fd = format!("{f}.dofs[{k}]");
                let d = d.get_ref();
                let v = DofSpec {
                    kind: d.kind.clone(),
                    axis: self.opt_vector(&d.axis, &format!("{fd}.axis"))?,
                    drive: self.opt_num(&d.drive, &format!("{fd}.drive"))?,
                    initial: self.opt_num(&d.initial, &format!("{fd}.initial"))?,
                    initial_rate: d
                        .initial_rate
                        .as_ref()
                        .map(|x| self.num_or_vec(x, &format!("{fd}.initial_rate")))
                        .transpose()?,
                };
                Ok(Spanned::new(b.dofs[k].span(), v))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(BodySpec {
            name: self.string(&b.name, &format!("{f}.name"))?,
            position: self.opt_vector(&b.position, &format!("{f}.position"))?,
            axes,
            mass: self.opt_num(&b.mass, &format!("{f}.mass"))?,
            com: self.opt_vector(&b.com, &format!("{f}.com"))?,
            inertia,
            dofs,
        })
    }

    fn joint(&self, j: &JointSpec, f: &str) -> Result<JointSpec> {
        Ok(JointSpec {
            name: self.string(&j.name, &format!("{f}.name"))?,
            node: self.string(&j.node, &format!("{f}.node"))?,
            body: self.opt_string(&j.body, &format!("{f}.body"))?,
            to_node: self.opt_string(&j.to_node, &format!("{f}.to_node"))?,
            kind: j.kind.clone(),
            axis: self.opt_vector(&j.axis, &format!("{f}.axis"))?,
            stiffness: self.opt_num(&j.stiffness, &format!("{f}.stiffness"))?,
            damping: self.opt_num(&j.damping, &format!("{f}.damping"))?,
            lock_angle: self.opt_num(&j.lock_angle, &format!("{f}.lock_angle"))?,
            lock_time: self.opt_num(&j.lock_time, &format!("{f}.lock_time"))?,
            initial_rate: self.opt_num(&j.initial_rate, &format!("{f}.initial_rate"))?,
        })
    }

    fn sensor(&self, s: &SensorSpec, f: &str) -> Result<SensorSpec> {
        Ok(SensorSpec {
            name: self.string(&s.name, &format!("{f}.name"))?,
            kind: s.kind.clone(),
            node: self.opt_string(&s.node, &format!("{f}.node"))?,
            beam: self.opt_string(&s.beam, &format!("{f}.beam"))?,
            at: self.opt_num(&s.at, &format!("{f}.at"))?,
            component: self.opt_string(&s.component, &format!("{f}.component"))?,
            joint: self.opt_string(&s.joint, &format!("{f}.joint"))?,
            body: self.opt_string(&s.body, &format!("{f}.body"))?,
            direction: self.opt_vector(&s.direction, &format!("{f}.direction"))?,
            dof: self.opt_num(&s.dof, &format!("{f}.dof"))?,
            frame: self.opt_string(&s.frame, &format!("{f}.frame"))?,
        })
    }
}

/// `text` with every identifier that names an index replaced by its value in
/// parentheses; number literals (`2e3`) are kept whole.
fn replace_idents(text: &str, indices: &[(String, i64)]) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_digit() || (c == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                let mut j = i + 1;
                if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                    j += 1;
                }
                if j < b.len() && b[j].is_ascii_digit() {
                    i = j;
                    while i < b.len() && b[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            out.push_str(&text[start..i]);
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            let word = &text[start..i];
            match indices.iter().rev().find(|(n, _)| n == word) {
                Some((_, v)) => out += &format!("({v})"),
                None => out.push_str(word),
            }
        } else {
            // whole characters (names may be non-ASCII, such as π)
            let ch = text[i..].chars().next().unwrap_or(' ');
            out.push(ch);
            i += ch.len_utf8();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_names_in_expressions_become_their_values() {
        let ix = [("i".to_string(), 3), ("k".to_string(), -2)];
        assert_eq!(
            replace_idents("i*h + sin(k) - 2e3", &ix),
            "(3)*h + sin((-2)) - 2e3"
        );
        assert_eq!(
            replace_idents("pi_i + xi + i1 + 1.5e-3*i", &ix),
            "pi_i + xi + i1 + 1.5e-3*(3)"
        );
        assert_eq!(replace_idents("π*i", &ix), "π*(3)");
    }
}

#[cfg(test)]
mod limit_tests {
    use super::*;
    use crate::model::expr::List;

    const NESTED: &str = r#"
[[repeat]]
index = "i"
to = "n"
  [[repeat.nodes]]
  name = "a{i}"
  position = ["i", 0, 0]
  [[repeat.repeat]]
  index = "j"
  to = "m"
    [[repeat.repeat.beams]]
    name = "b{i}_{j}"
    from = "a{i}"
    to = "a{i}"
    elements = 1
    section = "s"
"#;

    fn run(n: f64, m: f64, lim: Limits) -> Result<(Spec, Origins, Vec<RepeatSummary>)> {
        let spec = parse(NESTED, "n.toml").unwrap();
        let params = vec![("n".to_string(), n), ("m".to_string(), m)];
        expand(&spec, "n.toml", NESTED, &List(&params), &lim)
    }

    #[test]
    fn nested_ranges_multiply_and_are_checked_before_expanding() {
        let (spec, _, summary) = run(3.0, 2.0, Limits::default()).unwrap();
        assert_eq!(spec.nodes.len(), 3);
        let names: Vec<_> = spec
            .beams
            .iter()
            .map(|b| b.get_ref().name.get_ref().clone())
            .collect();
        assert_eq!(names, ["b1_1", "b1_2", "b2_1", "b2_2", "b3_1", "b3_2"]);
        assert_eq!(summary[0].path, "repeat[0]");
        assert_eq!(summary[1].path, "repeat[0].repeat[0]");
        assert_eq!((summary[1].iterations, summary[1].counts[1]), (6, 6));
        // 1e6 × 1e6 beams: refused by the count, in no time and without memory
        let lim = Limits::default();
        let e = run(1e6, 1e6, lim).err().unwrap();
        assert!(
            e.message.contains("elements") && e.message.contains("1000000000000"),
            "{e}"
        );
        let small = Limits { dofs: 100, ..lim };
        let e = run(20.0, 1.0, small).err().unwrap();
        assert!(
            e.message.contains("20 nodes × 6") && e.message.contains("dofs"),
            "{e}"
        );
        assert!(run(3.0, 2.0, small).is_ok());
    }
}
