//! The model file as written (user vocabulary), deserialized from TOML.
//!
//! Every field keeps its source span (`Spanned`) so that compilation can point at the
//! offending text. Unknown keys are errors everywhere. Numbers may be expressions
//! ([`Num`]); nothing is evaluated here.

use std::fmt;
use std::ops::Range;

use serde::de::{
    self, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess, Visitor,
};
use serde::Deserialize;

use super::error::ModelError;

/// A value with its byte range in the file, like `toml::Spanned`, but also accepting
/// values toml keeps no span for (tables made implicitly by dotted keys such as
/// `[sections.main]`'s `sections`, or `solver.dt = 1` at the top level), which
/// `toml::Spanned` rejects with a confusing message. Those get the empty span `0..0`,
/// which error reporting treats as "position unknown".
#[derive(Clone, Debug, PartialEq)]
pub struct Spanned<T> {
    span: Range<usize>,
    value: T,
}

impl<T> Spanned<T> {
    pub fn new(span: Range<usize>, value: T) -> Spanned<T> {
        Spanned { span, value }
    }
    pub fn span(&self) -> Range<usize> {
        self.span.clone()
    }
    pub fn get_ref(&self) -> &T {
        &self.value
    }
    pub fn into_inner(self) -> T {
        self.value
    }
}

// the protocol toml uses to hand out spans (serde_spanned 0.6, as used by toml 0.8)
const SPANNED_NAME: &str = "$__serde_spanned_private_Spanned";
const SPANNED_START: &str = "$__serde_spanned_private_start";
const SPANNED_END: &str = "$__serde_spanned_private_end";
const SPANNED_VALUE: &str = "$__serde_spanned_private_value";
const SPANNED_FIELDS: [&str; 3] = [SPANNED_START, SPANNED_END, SPANNED_VALUE];

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Spanned<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Spanned<T>, D::Error> {
        d.deserialize_struct(
            SPANNED_NAME,
            &SPANNED_FIELDS,
            SpannedVisitor(std::marker::PhantomData),
        )
    }
}

struct SpannedVisitor<T>(std::marker::PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for SpannedVisitor<T> {
    type Value = Spanned<T>;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a value")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Spanned<T>, A::Error> {
        let first: Option<String> = map.next_key()?;
        if first.as_deref() != Some(SPANNED_START) {
            // an unspanned table: `first` is its first real key
            let value =
                T::deserialize(de::value::MapAccessDeserializer::new(Replay { first, map }))?;
            return Ok(Spanned::new(0..0, value));
        }
        let start: usize = map.next_value()?;
        let mut end = None;
        let mut value = None;
        while let Some(k) = map.next_key::<String>()? {
            match k.as_str() {
                SPANNED_END => end = Some(map.next_value::<usize>()?),
                SPANNED_VALUE => value = Some(map.next_value::<T>()?),
                other => return Err(de::Error::unknown_field(other, &SPANNED_FIELDS)),
            }
        }
        match (end, value) {
            (Some(end), Some(value)) => Ok(Spanned::new(start..end, value)),
            _ => Err(de::Error::custom("incomplete span information")),
        }
    }
    // keys arrive as plain strings when toml has no span for them
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Spanned<T>, E> {
        let de: de::value::StrDeserializer<E> = v.into_deserializer();
        T::deserialize(de).map(|x| Spanned::new(0..0, x))
    }
    fn visit_string<E: de::Error>(self, v: String) -> Result<Spanned<T>, E> {
        self.visit_str(&v)
    }
}

/// A map access with its first key already taken out and put back in front.
struct Replay<A> {
    first: Option<String>,
    map: A,
}

impl<'de, A: MapAccess<'de>> MapAccess<'de> for Replay<A> {
    type Error = A::Error;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, A::Error> {
        match self.first.take() {
            Some(k) => seed.deserialize(k.into_deserializer()).map(Some),
            None => self.map.next_key_seed(seed),
        }
    }
    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, A::Error> {
        self.map.next_value_seed(seed)
    }
}

/// A number, or an expression string over the parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Num {
    Value(f64),
    Expr(String),
}

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Num, D::Error> {
        d.deserialize_any(NumVisitor)
    }
}

struct NumVisitor;

impl<'de> Visitor<'de> for NumVisitor {
    type Value = Num;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a number or an expression string")
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Num, E> {
        Ok(Num::Value(v as f64))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Num, E> {
        Ok(Num::Value(v as f64))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Num, E> {
        Ok(Num::Value(v))
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<Num, E> {
        Ok(Num::Expr(v.to_string()))
    }
}

/// An array of numbers or expressions; the length is checked where it is used.
pub type Vector = Vec<Spanned<Num>>;

/// A number or an array of numbers (inertia rows, scalar or vector initial rates).
#[derive(Clone, Debug, PartialEq)]
pub enum NumOrVec {
    Num(Num),
    Vec(Vector),
}

impl<'de> Deserialize<'de> for NumOrVec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<NumOrVec, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = NumOrVec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, an expression string or an array of them")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<NumOrVec, E> {
                NumVisitor.visit_i64(v).map(NumOrVec::Num)
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<NumOrVec, E> {
                NumVisitor.visit_u64(v).map(NumOrVec::Num)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<NumOrVec, E> {
                NumVisitor.visit_f64(v).map(NumOrVec::Num)
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<NumOrVec, E> {
                NumVisitor.visit_str(v).map(NumOrVec::Num)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<NumOrVec, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                Ok(NumOrVec::Vec(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// A TOML table of named entries (`[materials.steel]`, `[parameters]`), in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct Table<V>(pub Vec<(Spanned<String>, Spanned<V>)>);

impl<V> Default for Table<V> {
    fn default() -> Self {
        Table(Vec::new())
    }
}

impl<'de, V: Deserialize<'de>> Deserialize<'de> for Table<V> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Table<V>, D::Error> {
        struct TV<V>(std::marker::PhantomData<V>);
        impl<'de, V: Deserialize<'de>> Visitor<'de> for TV<V> {
            type Value = Table<V>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Table<V>, A::Error> {
                let mut v = Vec::new();
                while let Some(k) = map.next_key()? {
                    v.push((k, map.next_value()?));
                }
                Ok(Table(v))
            }
        }
        d.deserialize_map(TV(std::marker::PhantomData))
    }
}

/// `name = 1.0`, `name = "2*L"` (earlier parameters only) or
/// `name = { value = 1.0, unit = "m", description = "...", min = 0, max = 10,
/// integer = true }` (the bounds are checked on the value and on every `--set`).
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    Plain(Num),
    Full(ParamTable),
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamTable {
    pub value: Spanned<Num>,
    pub unit: Option<String>,
    pub description: Option<String>,
    /// smallest value the model is valid for (an expression of earlier parameters)
    pub min: Option<Spanned<Num>>,
    /// largest value the model is valid for
    pub max: Option<Spanned<Num>>,
    /// the value must be a whole number (a count: elements, bays)
    pub integer: Option<bool>,
}

impl<'de> Deserialize<'de> for ParamValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<ParamValue, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = ParamValue;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, an expression string or { value, unit, description }")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ParamValue, E> {
                NumVisitor.visit_i64(v).map(ParamValue::Plain)
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ParamValue, E> {
                NumVisitor.visit_u64(v).map(ParamValue::Plain)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ParamValue, E> {
                NumVisitor.visit_f64(v).map(ParamValue::Plain)
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<ParamValue, E> {
                NumVisitor.visit_str(v).map(ParamValue::Plain)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ParamValue, A::Error> {
                ParamTable::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(ParamValue::Full)
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    pub model: Option<Spanned<ModelInfo>>,
    #[serde(default)]
    pub parameters: Table<ParamValue>,
    #[serde(default)]
    pub materials: Table<Material>,
    #[serde(default)]
    pub sections: Table<Section>,
    #[serde(default)]
    pub nodes: Vec<Spanned<NodeSpec>>,
    #[serde(default)]
    pub beams: Vec<Spanned<BeamSpec>>,
    #[serde(default)]
    pub supports: Vec<Spanned<SupportSpec>>,
    #[serde(default)]
    pub loads: Vec<Spanned<LoadSpec>>,
    pub environment: Option<Spanned<Environment>>,
    #[serde(default)]
    pub bodies: Vec<Spanned<BodySpec>>,
    #[serde(default)]
    pub joints: Vec<Spanned<JointSpec>>,
    #[serde(default)]
    pub sensors: Vec<Spanned<SensorSpec>>,
    pub solver: Option<Spanned<SolverSpec>>,
    pub initial: Option<Spanned<InitialSpec>>,
    /// `[[repeat]]`: entries generated from an index (expanded by `repeat::expand`)
    #[serde(default)]
    pub repeat: Vec<Spanned<RepeatSpec>>,
}

/// `[[repeat]]`: the entries below it are written once and generated for every value of
/// `index` from `from` (default 1) to `to` (inclusive); `{expr}` in their strings is
/// replaced by the integer value of `expr`, and the index is a number in their
/// expressions. Repeats nest (`[[repeat.repeat]]`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RepeatSpec {
    pub index: Spanned<String>,
    pub from: Option<Spanned<Num>>,
    pub to: Spanned<Num>,
    #[serde(default)]
    pub nodes: Vec<Spanned<NodeSpec>>,
    #[serde(default)]
    pub beams: Vec<Spanned<BeamSpec>>,
    #[serde(default)]
    pub supports: Vec<Spanned<SupportSpec>>,
    #[serde(default)]
    pub loads: Vec<Spanned<LoadSpec>>,
    #[serde(default)]
    pub bodies: Vec<Spanned<BodySpec>>,
    #[serde(default)]
    pub joints: Vec<Spanned<JointSpec>>,
    #[serde(default)]
    pub sensors: Vec<Spanned<SensorSpec>>,
    #[serde(default)]
    pub repeat: Vec<Spanned<RepeatSpec>>,
}

/// `[initial]`: the whole model starts in rigid rotation with `angular_velocity` about
/// `center` (default the origin), or, with `steady = true`, in the steady rotation of its
/// constant-speed hub (centrifugally stretched, at rest in the rotating frame); with
/// `consistent_velocity = true` the coordinates without an `initial_rate` take the
/// velocity that strains nothing, given the rates that are set.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    pub angular_velocity: Option<Spanned<Vector>>,
    pub center: Option<Spanned<Vector>>,
    pub steady: Option<Spanned<bool>>,
    pub consistent_velocity: Option<Spanned<bool>>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelInfo {
    pub name: Option<Spanned<String>>,
    pub description: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    #[serde(rename = "E")]
    pub e: Spanned<Num>,
    #[serde(rename = "G")]
    pub g: Spanned<Num>,
    pub density: Spanned<Num>,
}

/// Direct properties (`EA` ... `rhoIz`) or a `shape` of a `material`; which keys belong
/// together is checked by compilation.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Section {
    #[serde(rename = "EA")]
    pub ea: Option<Spanned<Num>>,
    #[serde(rename = "EIy")]
    pub eiy: Option<Spanned<Num>>,
    #[serde(rename = "EIz")]
    pub eiz: Option<Spanned<Num>>,
    #[serde(rename = "GJ")]
    pub gj: Option<Spanned<Num>>,
    #[serde(rename = "rhoA")]
    pub rho_a: Option<Spanned<Num>>,
    #[serde(rename = "rhoIy")]
    pub rho_iy: Option<Spanned<Num>>,
    #[serde(rename = "rhoIz")]
    pub rho_iz: Option<Spanned<Num>>,
    pub shape: Option<Spanned<Shape>>,
    pub material: Option<Spanned<String>>,
    pub outer_diameter: Option<Spanned<Num>>,
    pub inner_diameter: Option<Spanned<Num>>,
    pub diameter: Option<Spanned<Num>>,
    pub width: Option<Spanned<Num>>,
    pub height: Option<Spanned<Num>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shape {
    Tube,
    Circle,
    Rectangle,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeSpec {
    pub name: Spanned<String>,
    pub position: Spanned<Vector>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BeamSpec {
    pub name: Spanned<String>,
    pub from: Spanned<String>,
    pub to: Spanned<String>,
    pub elements: Spanned<Num>,
    pub section: Spanned<String>,
    pub orientation: Option<Spanned<Vector>>,
    pub arc_center: Option<Spanned<Vector>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SupportType {
    Clamped,
    Pinned,
    Free,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupportSpec {
    pub node: Spanned<String>,
    #[serde(rename = "type")]
    pub kind: Spanned<SupportType>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    pub node: Spanned<String>,
    pub force: Option<Spanned<Vector>>,
    pub moment: Option<Spanned<Vector>>,
    /// time factor on force and moment (dynamics only), an expression in `t`
    pub scale: Option<Spanned<Num>>,
    /// only `false` (dead loads) is supported
    pub follower: Option<Spanned<bool>>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    pub gravity: Option<Spanned<Vector>>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    pub name: Spanned<String>,
    pub position: Option<Spanned<Vector>>,
    pub axes: Option<Spanned<Vec<Spanned<Vector>>>>,
    pub mass: Option<Spanned<Num>>,
    pub com: Option<Spanned<Vector>>,
    /// three diagonal entries or three rows
    pub inertia: Option<Spanned<Vec<Spanned<NumOrVec>>>>,
    #[serde(default)]
    pub dofs: Vec<Spanned<DofSpec>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DofType {
    Translation,
    Rotation,
    FreeRotation,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DofSpec {
    #[serde(rename = "type")]
    pub kind: Spanned<DofType>,
    pub axis: Option<Spanned<Vector>>,
    pub drive: Option<Spanned<Num>>,
    pub initial: Option<Spanned<Num>>,
    /// a number; for `free_rotation` the initial angular velocity vector (global frame)
    pub initial_rate: Option<Spanned<NumOrVec>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointType {
    Rigid,
    Hinge,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    pub name: Spanned<String>,
    pub node: Spanned<String>,
    pub body: Option<Spanned<String>>,
    pub to_node: Option<Spanned<String>>,
    #[serde(rename = "type")]
    pub kind: Spanned<JointType>,
    pub axis: Option<Spanned<Vector>>,
    pub stiffness: Option<Spanned<Num>>,
    pub damping: Option<Spanned<Num>>,
    pub lock_angle: Option<Spanned<Num>>,
    pub lock_time: Option<Spanned<Num>>,
    pub initial_rate: Option<Spanned<Num>>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorType {
    Node,
    Position,
    Section,
    Hinge,
    Body,
    Direction,
    Energy,
    Driver,
    BeamNodes,
    BodyFrame,
}

impl SensorType {
    pub fn as_str(self) -> &'static str {
        match self {
            SensorType::Node => "node",
            SensorType::Position => "position",
            SensorType::Section => "section",
            SensorType::Hinge => "hinge",
            SensorType::Body => "body",
            SensorType::Direction => "direction",
            SensorType::Energy => "energy",
            SensorType::Driver => "driver",
            SensorType::BeamNodes => "beam_nodes",
            SensorType::BodyFrame => "body_frame",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    pub name: Spanned<String>,
    #[serde(rename = "type")]
    pub kind: Spanned<SensorType>,
    pub node: Option<Spanned<String>>,
    pub beam: Option<Spanned<String>>,
    pub at: Option<Spanned<Num>>,
    pub component: Option<Spanned<String>>,
    pub joint: Option<Spanned<String>>,
    pub body: Option<Spanned<String>>,
    pub direction: Option<Spanned<Vector>>,
    /// driver sensors: index into the body's `[[bodies.dofs]]` (from 0)
    pub dof: Option<Spanned<Num>>,
    /// section sensors: output frame (only `local`, the convected frame)
    pub frame: Option<Spanned<String>>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    pub t_end: Option<Spanned<Num>>,
    pub dt: Option<Spanned<Num>>,
    pub output_dt: Option<Spanned<Num>>,
    pub rho_inf: Option<Spanned<Num>>,
    pub tol: Option<Spanned<Num>>,
    pub max_iter: Option<Spanned<Num>>,
    /// "modified" (default) or "full"
    pub newton: Option<Spanned<String>>,
    pub dt_min: Option<Spanned<Num>>,
    /// relative local error target: turns on adaptive steps
    pub accuracy: Option<Spanned<Num>>,
    pub dt_max: Option<Spanned<Num>>,
    pub load_steps: Option<Spanned<Num>>,
    pub rayleigh_alpha: Option<Spanned<Num>>,
    pub rayleigh_beta: Option<Spanned<Num>>,
}

/// Parses model text; `file` is only used in error messages.
pub fn parse(text: &str, file: &str) -> Result<Spec, ModelError> {
    toml::from_str::<Spec>(text).map_err(|e| toml_error(text, file, &e))
}

/// Turns a toml/serde error into a located one, recovering the field path (which toml
/// does not expose) from the error's span in a generic parse of the same text.
fn toml_error(text: &str, file: &str, e: &toml::de::Error) -> ModelError {
    let mut message = e.message().trim().replace('\n', "; ");
    if message.is_empty() {
        // the toml crate gives no text for some lexer errors (a control character in a
        // comment: a probe in session 48 read `FILE:1:4: ` and nothing else)
        let at = e.span().map_or(0, |s| s.start);
        message = match text.get(at..).and_then(|t| t.chars().next()) {
            Some(c) if c.is_control() && c != '\t' => format!(
                "control character U+{:04X} is not allowed in TOML, not even in a comment; \
                 remove it",
                c as u32
            ),
            Some(c) => format!("invalid TOML at `{}`", c.escape_debug()),
            None => "invalid TOML (the file ends in the middle of a value)".into(),
        };
    }
    let Some(span) = e.span() else {
        return ModelError::file(file, None, message);
    };
    let field = match toml::from_str::<Spanned<Tree>>(text) {
        Ok(tree) => {
            let joined = locate(&tree, &span).unwrap_or_default().join("");
            let mut field = joined.trim_start_matches('.').to_string();
            // serde reports a missing key at the table that lacks it, an unknown key at
            // the key itself (which the tree has no span for)
            let named = ["missing field `", "unknown field `"]
                .iter()
                .find_map(|p| message.strip_prefix(p))
                .and_then(|m| m.split('`').next());
            if let Some(name) = named {
                if !field.is_empty() {
                    field.push('.');
                }
                field += name;
            }
            field
        }
        Err(_) => syntax_error_field(text, span.start),
    };
    let mut err = ModelError::at(file, text, span, field.clone(), message);
    if field.is_empty() {
        err.field = None;
    }
    err
}

/// Any TOML value with spans, only to map an error span back to a key path.
enum Tree {
    Table(Vec<(String, Spanned<Tree>)>),
    Array(Vec<Spanned<Tree>>),
    Leaf,
}

impl<'de> Deserialize<'de> for Tree {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Tree, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Tree;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("any TOML value")
            }
            fn visit_bool<E: de::Error>(self, _: bool) -> Result<Tree, E> {
                Ok(Tree::Leaf)
            }
            fn visit_i64<E: de::Error>(self, _: i64) -> Result<Tree, E> {
                Ok(Tree::Leaf)
            }
            fn visit_u64<E: de::Error>(self, _: u64) -> Result<Tree, E> {
                Ok(Tree::Leaf)
            }
            fn visit_f64<E: de::Error>(self, _: f64) -> Result<Tree, E> {
                Ok(Tree::Leaf)
            }
            fn visit_str<E: de::Error>(self, _: &str) -> Result<Tree, E> {
                Ok(Tree::Leaf)
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Tree, A::Error> {
                let mut v = Vec::new();
                while let Some(k) = map.next_key()? {
                    v.push((k, map.next_value()?));
                }
                Ok(Tree::Table(v))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Tree, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element()? {
                    v.push(x);
                }
                Ok(Tree::Array(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// Path pieces (`key`, `.key`, `[i]`) to the innermost value whose span contains `span`,
/// looking through values without a span; None if nothing below `node` contains it.
fn locate(node: &Spanned<Tree>, span: &Range<usize>) -> Option<Vec<String>> {
    let children: Vec<(String, &Spanned<Tree>)> = match node.get_ref() {
        Tree::Table(entries) => entries.iter().map(|(k, v)| (k.clone(), v)).collect(),
        Tree::Array(items) => items
            .iter()
            .enumerate()
            .map(|(i, v)| (format!("[{i}]"), v))
            .collect(),
        Tree::Leaf => Vec::new(),
    };
    for (label, child) in children {
        if let Some(mut path) = locate(child, span) {
            let dot = if label.starts_with('[') || label.is_empty() {
                ""
            } else {
                "."
            };
            path.insert(0, format!("{dot}{label}"));
            return Some(path);
        }
    }
    let own = extent(node)?;
    (own.start <= span.start && span.end <= own.end).then(Vec::new)
}

/// A node's span, or for a table made by dotted keys the range its values cover.
fn extent(node: &Spanned<Tree>) -> Option<Range<usize>> {
    if node.span() != (0..0) {
        return Some(node.span());
    }
    let children: Vec<&Spanned<Tree>> = match node.get_ref() {
        Tree::Table(entries) => entries.iter().map(|(_, v)| v).collect(),
        Tree::Array(items) => items.iter().collect(),
        Tree::Leaf => Vec::new(),
    };
    children
        .into_iter()
        .filter_map(extent)
        .reduce(|a, b| a.start.min(b.start)..a.end.max(b.end))
}

/// Best guess at the field of a TOML syntax error: the enclosing table header and the key
/// on the error's line.
fn syntax_error_field(text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next().unwrap_or("");
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim().trim_matches('"').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('['));
    let header = text[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| {
            l.trim_start_matches('[')
                .split(']')
                .next()
                .unwrap_or("")
                .trim()
                .to_string()
        });
    match (header, key) {
        (Some(h), Some(k)) => format!("{h}.{k}"),
        (None, Some(k)) => k,
        (Some(h), None) => h,
        (None, None) => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> ModelError {
        parse(text, "m.toml").unwrap_err()
    }

    #[test]
    fn numbers_expressions_and_parameter_forms() {
        let s = parse(
            "[parameters]\nL = 2\nEI = { value = 1e4, unit = \"N*m^2\" }\nc = \"2*L\"\n\
             [[nodes]]\nname = \"a\"\nposition = [0, \"L\", 1.5]\n",
            "m.toml",
        )
        .unwrap();
        let names: Vec<_> = s
            .parameters
            .0
            .iter()
            .map(|(k, _)| k.get_ref().as_str())
            .collect();
        assert_eq!(names, ["L", "EI", "c"], "file order is kept");
        let pos: Vec<_> = s.nodes[0]
            .get_ref()
            .position
            .get_ref()
            .iter()
            .map(|x| x.get_ref().clone())
            .collect();
        assert_eq!(
            pos,
            [Num::Value(0.0), Num::Expr("L".into()), Num::Value(1.5)]
        );
    }

    #[test]
    fn errors_carry_line_and_field_path() {
        let e = err("[[beams]]\nname = \"a\"\nfrom = \"x\"\nto = \"y\"\nsection = \"s\"\n\n[[beams]]\nname = \"b\"\n");
        assert_eq!(e.line, Some(1));
        assert_eq!(e.field.as_deref(), Some("beams[0].elements"));

        let e = err("[[nodes]]\nname = \"a\"\nposition = [0, 0, 0]\npositon = 1\n");
        assert_eq!((e.line, e.column), (Some(4), Some(1)));
        assert_eq!(e.field.as_deref(), Some("nodes[0].positon"));
        assert!(e.message.contains("unknown field"), "{e}");

        let e = err("[[nodes]]\nname = \"a\"\nposition = [0, true, 0]\n");
        assert_eq!(e.field.as_deref(), Some("nodes[0].position[1]"));
        assert_eq!(e.line, Some(3));

        let e = err("[solver]\ndt = \n");
        assert_eq!(e.line, Some(2));
        assert_eq!(e.field.as_deref(), Some("solver.dt"));

        // tables made by dotted keys have no span of their own
        let e = err("[sections]\nmain.EA = 1\nmain.foo = 2\n");
        assert_eq!(e.field.as_deref(), Some("sections.main.foo"));
        assert_eq!(e.line, Some(3));
        let s = parse("solver.dt = 0.5\n[sections]\nmain.EA = 1\n", "m.toml").unwrap();
        assert!(s.solver.is_some() && s.sections.0[0].0.get_ref() == "main");

        let e = err("[[supports]]\nnode = \"a\"\ntype = \"clampd\"\n");
        assert_eq!(e.field.as_deref(), Some("supports[0].type"));
        assert!(
            e.to_string()
                .starts_with("m.toml:3:8: field `supports[0].type`: unknown variant"),
            "{e}"
        );
    }
}
