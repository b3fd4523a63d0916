//! The declarative parameter spec: one description per plugin parameter drives the
//! WGSL uniform struct, the packed uniform bytes, RON presets (only non-default values
//! are saved; bad values fail with the path `plugin.param`) and the generated UI.
//!
//! Uniform layout follows WGSL's rules for uniform buffers: scalars (f32, i32, u32)
//! are 4-byte aligned, vec3/vec4 are 16-byte aligned (a vec3 takes 12 bytes, the next
//! scalar may fill its last 4), and the struct size is rounded up to 16. Bool and enum
//! parameters are u32. Transfer-function curves are not uniforms: the plugin bakes
//! them into a texture.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::tf::TfCurve;

#[derive(Debug, Clone, PartialEq)]
pub enum ParamKind {
    Float {
        min: f32,
        max: f32,
        /// Logarithmic slider (min must be > 0).
        log: bool,
        default: f32,
    },
    Int {
        min: i32,
        max: i32,
        default: i32,
    },
    Bool {
        default: bool,
    },
    Enum {
        options: Vec<&'static str>,
        default: usize,
    },
    /// Straight RGBA in \[0,1\].
    Color {
        default: [f32; 4],
    },
    Vec3 {
        min: f32,
        max: f32,
        default: [f32; 3],
    },
    Tf {
        default: TfCurve,
    },
    Tf2d {
        default: crate::tf2d::Tf2d,
    },
    /// A file beside the data (e.g. a label volume); empty = none. Relative paths in a
    /// preset are relative to the preset file. Not a uniform.
    Path {
        default: &'static str,
    },
    /// A named volume input: the name of one of the document's `volumes:` (a preset's
    /// named volumes, each with its own grid and spacing), or empty for the document's
    /// own volume. Not a uniform: the plugin reads the volume through
    /// `GpuInit::input` and `CpuContext::input`.
    Volume {
        components: Components,
    },
}

/// What a named volume input ([`ParamKind::Volume`]) must hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Components {
    /// One component (a scalar volume).
    Scalar,
    /// Two or three components (a vector field), kept as they are.
    Vector,
    /// Any volume.
    Any,
}

impl Components {
    /// Whether a volume of `n` components is one.
    pub fn admits(self, n: u32) -> bool {
        match self {
            Components::Scalar => n == 1,
            Components::Vector => n >= 2,
            Components::Any => true,
        }
    }
    pub fn describe(self) -> &'static str {
        match self {
            Components::Scalar => "a scalar volume",
            Components::Vector => "a vector volume (2 or 3 components)",
            Components::Any => "a volume",
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Key in presets and in WGSL (`params.<key>`): lowercase identifier.
    pub key: &'static str,
    pub label: &'static str,
    pub doc: &'static str,
    pub kind: ParamKind,
    /// A change needs a recomposed pipeline (the value changes the shader structure).
    pub structural: bool,
    /// Shown in the UI only while the enumeration `.0` has the value `.1` (a parameter
    /// that one mode reads); presets and uniforms hold it whatever the mode.
    pub shown_when: Option<(&'static str, &'static str)>,
    /// A float the window can play (advance at a speed each frame) and `vwb render`
    /// can sweep into an image sequence ([`Animation`]).
    pub animation: Option<Animation>,
    /// The element of a repeated group (a light, a clip shape, a label's TF, an
    /// isosurface) this parameter belongs to ([`Group`]); None for a plain parameter.
    pub element: Option<Element>,
}

/// A repeated group of parameters: `count` elements with the same members (lights,
/// clip shapes, per-label transfer functions, isovalues). Presets, uniforms, WGSL and
/// experiment grids see flat keys made from templates (`light{}_on` → `light0_on`,
/// `light1_on`, …), so a group changes no file format; the window draws each element
/// under its own header, hides the elements that are not in use, and a plugin reads
/// element i's value with `values.float(group.key("iso{}", i))` instead of a
/// hand-kept table of keys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Group {
    /// The element's name in the window ("Light" → "Light 0", "Light 1", …).
    pub name: &'static str,
    pub count: usize,
    /// The template of a member that switches an element on: a bool, an enumeration
    /// whose first option means off (`shape{}_kind`: "off"), or an int that is −1
    /// while the element is unused (`range{}_from`).
    pub switch: Option<&'static str>,
    /// An int parameter (outside the group) holding how many elements are in use:
    /// those at or past it are hidden (`shade.isosurface`'s `count`).
    pub limit: Option<&'static str>,
}

/// A group member's key split around its element index: `shape0_kind` of element 0 →
/// (`shape`, `kind`); `iso2` of element 2 → (`iso`, ``). The index is the first run of
/// digits equal to it that is neither preceded nor followed by another digit.
pub fn split_member(key: &str, index: usize) -> Option<(&str, &str)> {
    let digits = index.to_string();
    let bytes = key.as_bytes();
    let mut from = 0;
    while let Some(at) = key[from..].find(&digits).map(|p| p + from) {
        let end = at + digits.len();
        let before = at > 0 && bytes[at - 1].is_ascii_digit();
        let after = end < bytes.len() && bytes[end].is_ascii_digit();
        if !before && !after && at > 0 {
            let field = key[end..].strip_prefix('_').unwrap_or(&key[end..]);
            return Some((&key[..at], field));
        }
        from = at + 1;
    }
    None
}

/// A plugin's parameters as a preset writes them, with each repeated group given as a
/// list expanded to the flat keys: `"shape": [(kind: "box", center: (..)), ..]` is
/// `shape0_kind`, `shape0_center`, …; a group whose members have no field after the
/// index is a list of values (`"iso": [0.3, 0.5]` is `iso0`, `iso1`). Elements the list
/// leaves out keep their defaults. Other entries pass through. Errors give the key and
/// the cause (a list longer than the group, an unknown field, an element that is not a
/// map, a key given both ways).
pub fn flatten_groups(
    specs: &[ParamSpec],
    given: &std::collections::BTreeMap<String, ron::Value>,
) -> Result<Vec<(String, ron::Value)>, (String, String)> {
    let lists = group_lists(specs);
    let mut out: Vec<(String, ron::Value)> = Vec::new();
    for (key, value) in given {
        let (Some((fields, count)), ron::Value::Seq(items)) = (lists.get(key.as_str()), value)
        else {
            out.push((key.clone(), value.clone()));
            continue;
        };
        if items.len() > *count {
            return Err((
                key.clone(),
                format!("{} elements, but the group has {count}", items.len()),
            ));
        }
        let names = || fields.keys().copied().collect::<Vec<_>>().join(", ");
        for (i, item) in items.iter().enumerate() {
            let pairs: Vec<(String, &ron::Value)> = match (fields.get(""), item) {
                (Some(_), v) if fields.len() == 1 => vec![(String::new(), v)],
                (_, ron::Value::Map(m)) => m
                    .iter()
                    .map(|(k, v)| match k {
                        ron::Value::String(s) => Ok((s.clone(), v)),
                        other => Err((
                            format!("{key}[{i}]"),
                            format!("a field name is a plain name, not {other:?}"),
                        )),
                    })
                    .collect::<Result<_, _>>()?,
                _ => {
                    return Err((
                        format!("{key}[{i}]"),
                        format!("an element is a map of its fields ({})", names()),
                    ));
                }
            };
            for (field, v) in pairs {
                let flat = fields
                    .get(field.as_str())
                    .and_then(|keys| keys.get(i).copied().flatten())
                    .ok_or_else(|| {
                        (
                            format!("{key}[{i}]"),
                            format!("unknown field '{field}' (known: {})", names()),
                        )
                    })?;
                if given.contains_key(flat) {
                    return Err((
                        format!("{key}[{i}]"),
                        format!("'{flat}' is also given as a key of its own"),
                    ));
                }
                out.push((flat.to_string(), v.clone()));
            }
        }
    }
    Ok(out)
}

/// A group's members by field: field → the member's key of each element.
type ListFields<'a> = std::collections::BTreeMap<&'a str, Vec<Option<&'static str>>>;

/// The lists a preset may write: list name → its fields and the group's size. A plain
/// parameter of the same name (a Vec3 is a list in RON too) keeps its name.
fn group_lists(
    specs: &[ParamSpec],
) -> std::collections::BTreeMap<&'static str, (ListFields<'static>, usize)> {
    let mut lists: std::collections::BTreeMap<&'static str, (ListFields<'static>, usize)> =
        Default::default();
    for spec in specs {
        let Some(e) = spec.element else { continue };
        let Some((list, field)) = split_member(spec.key, e.index) else {
            continue;
        };
        let (fields, count) = lists.entry(list).or_default();
        *count = e.group.count;
        let keys = fields
            .entry(field)
            .or_insert_with(|| vec![None; e.group.count]);
        if let Some(slot) = keys.get_mut(e.index) {
            *slot = Some(spec.key);
        }
    }
    lists.retain(|list, _| !specs.iter().any(|p| p.key == *list));
    lists
}

/// The inverse of [`flatten_groups`], as a preset is saved: the flat keys of each
/// repeated group become one list, element i a map of its given fields (`shape0_kind`,
/// `shape1_center` → `"shape": [{"kind": ..}, {"center": ..}]`), or, for a group whose
/// members have no field after the index, the element's value (`iso0` → `"iso": [..]`,
/// elements before the last given one written with their defaults). The list ends at
/// its last given element; other entries pass through.
pub fn group_flat_keys(
    specs: &[ParamSpec],
    flat: std::collections::BTreeMap<String, ron::Value>,
) -> std::collections::BTreeMap<String, ron::Value> {
    use std::collections::BTreeMap;
    let lists = group_lists(specs);
    let mut out = BTreeMap::new();
    let mut elements: BTreeMap<&str, Vec<BTreeMap<&str, ron::Value>>> = BTreeMap::new();
    for (key, value) in flat {
        let member = lists.iter().find_map(|(list, (fields, _))| {
            fields.iter().find_map(|(field, keys)| {
                let i = keys.iter().position(|k| *k == Some(key.as_str()))?;
                Some((*list, *field, i))
            })
        });
        let Some((list, field, i)) = member else {
            out.insert(key, value);
            continue;
        };
        let items = elements.entry(list).or_default();
        if items.len() <= i {
            items.resize_with(i + 1, BTreeMap::new);
        }
        items[i].insert(field, value);
    }
    for (list, items) in elements {
        let fields = &lists[list].0;
        let values_only = fields.len() == 1 && fields.contains_key("");
        let seq = items
            .into_iter()
            .enumerate()
            .map(|(i, mut item)| {
                if values_only {
                    // an element left out of the middle is written with its default
                    return item.remove("").unwrap_or_else(|| {
                        fields[""][i]
                            .and_then(|k| specs.iter().find(|s| s.key == k))
                            .map_or(ron::Value::Unit, |s| s.default_value().to_ron())
                    });
                }
                let mut map = ron::Map::new();
                for (field, v) in item {
                    map.insert(ron::Value::String(field.to_string()), v);
                }
                ron::Value::Map(map)
            })
            .collect();
        out.insert(list.to_string(), ron::Value::Seq(seq));
    }
    out
}

/// Where a parameter sits in a [`Group`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Element {
    pub group: Group,
    pub index: usize,
}

impl Group {
    pub const fn new(name: &'static str, count: usize) -> Self {
        Self {
            name,
            count,
            switch: None,
            limit: None,
        }
    }
    /// The member (a key template) that switches an element on or off.
    pub const fn switch(mut self, template: &'static str) -> Self {
        self.switch = Some(template);
        self
    }
    /// The int parameter holding how many elements are in use.
    pub const fn limit(mut self, key: &'static str) -> Self {
        self.limit = Some(key);
        self
    }
    /// The key of element `i` from a template with one `{}` (`"light{}_on"`, 1 →
    /// `"light1_on"`); made once per distinct key and kept for the process (specs hold
    /// `&'static str`).
    pub fn key(&self, template: &str, i: usize) -> &'static str {
        indexed(template, i)
    }
    /// The specs of every element, element by element: `element(i)` gives element i's
    /// members, with keys from [`Group::key`].
    pub fn specs(&self, element: impl Fn(usize) -> Vec<ParamSpec>) -> Vec<ParamSpec> {
        (0..self.count)
            .flat_map(|index| {
                element(index).into_iter().map(move |mut s| {
                    s.element = Some(Element {
                        group: *self,
                        index,
                    });
                    s
                })
            })
            .collect()
    }
    /// Whether element `index` is switched on (always, without a switch).
    pub fn is_on(&self, index: usize, values: &ParamValues) -> bool {
        let Some(template) = self.switch else {
            return true;
        };
        match values.get(indexed(template, index)) {
            Some(ParamValue::Bool(b)) => *b,
            Some(ParamValue::Enum(e)) => e != "off",
            Some(ParamValue::Int(i)) => *i >= 0,
            _ => true,
        }
    }
    /// Whether element `index` is in use under the group's limit.
    pub fn in_use(&self, index: usize, values: &ParamValues) -> bool {
        match self.limit.and_then(|k| values.get(k)) {
            Some(ParamValue::Int(n)) => (index as i64) < i64::from(*n),
            _ => true,
        }
    }
}

/// `template` (one `{}`) with `i` in place of the braces, as a `&'static str` made
/// once per distinct result.
pub fn indexed(template: &str, i: usize) -> &'static str {
    interned(template.replacen("{}", &i.to_string(), 1))
}

/// A generated key, label or id as `&'static str` (parameter specs and plugin
/// metadata need them), leaked once per distinct string: reloading a user plugin or
/// asking a plugin for its specs again reuses the same allocation.
pub fn interned(s: String) -> &'static str {
    use std::sync::{Mutex, OnceLock};
    static ALL: OnceLock<Mutex<std::collections::HashSet<&'static str>>> = OnceLock::new();
    let mut all = ALL
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    if let Some(&known) = all.get(s.as_str()) {
        return known;
    }
    let leaked: &'static str = Box::leak(s.into_boxed_str());
    all.insert(leaked);
    leaked
}

/// How a float parameter animates. Where the parameter stays out of the plugin's
/// passes' `depends_on` (`flow.arrival`'s `time`), playing it changes only a uniform
/// and every frame costs a static frame; where it is in them (`flow.lic3d`'s phase in
/// precomputed mode) every frame reruns them (docs/flow.md measures both).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Animation {
    /// A time (e.g. `flow.arrival`'s `time`): plays from its minimum to its maximum
    /// once; `vwb render --time T` sets it.
    Clock,
    /// A periodic value (e.g. a phase in degrees): plays in a loop.
    Cycle,
}

impl ParamSpec {
    pub fn float(key: &'static str, label: &'static str, min: f32, max: f32, default: f32) -> Self {
        Self::new(
            key,
            label,
            ParamKind::Float {
                min,
                max,
                log: false,
                default,
            },
        )
    }
    pub fn float_log(
        key: &'static str,
        label: &'static str,
        min: f32,
        max: f32,
        default: f32,
    ) -> Self {
        Self::new(
            key,
            label,
            ParamKind::Float {
                min,
                max,
                log: true,
                default,
            },
        )
    }
    pub fn int(key: &'static str, label: &'static str, min: i32, max: i32, default: i32) -> Self {
        Self::new(key, label, ParamKind::Int { min, max, default })
    }
    pub fn boolean(key: &'static str, label: &'static str, default: bool) -> Self {
        Self::new(key, label, ParamKind::Bool { default })
    }
    pub fn enumeration(
        key: &'static str,
        label: &'static str,
        options: &[&'static str],
        default: usize,
    ) -> Self {
        Self::new(
            key,
            label,
            ParamKind::Enum {
                options: options.to_vec(),
                default,
            },
        )
    }
    pub fn color(key: &'static str, label: &'static str, default: [f32; 4]) -> Self {
        Self::new(key, label, ParamKind::Color { default })
    }
    pub fn vec3(key: &'static str, label: &'static str, min: f32, max: f32, d: [f32; 3]) -> Self {
        Self::new(
            key,
            label,
            ParamKind::Vec3 {
                min,
                max,
                default: d,
            },
        )
    }
    pub fn path(key: &'static str, label: &'static str, default: &'static str) -> Self {
        Self::new(key, label, ParamKind::Path { default })
    }
    /// A named volume input ([`ParamKind::Volume`]); its default is the document's
    /// own volume.
    pub fn volume(key: &'static str, label: &'static str, components: Components) -> Self {
        Self::new(key, label, ParamKind::Volume { components })
    }
    pub fn tf2d(key: &'static str, label: &'static str, default: crate::tf2d::Tf2d) -> Self {
        Self::new(key, label, ParamKind::Tf2d { default })
    }
    pub fn tf(key: &'static str, label: &'static str, default: TfCurve) -> Self {
        Self::new(key, label, ParamKind::Tf { default })
    }
    pub fn new(key: &'static str, label: &'static str, kind: ParamKind) -> Self {
        Self {
            key,
            label,
            doc: "",
            kind,
            structural: false,
            shown_when: None,
            animation: None,
            element: None,
        }
    }
    /// The animation clock ([`Animation::Clock`]).
    pub fn clock(mut self) -> Self {
        self.animation = Some(Animation::Clock);
        self
    }
    /// A periodic animated value ([`Animation::Cycle`]).
    pub fn cycle(mut self) -> Self {
        self.animation = Some(Animation::Cycle);
        self
    }
    pub fn with_doc(mut self, doc: &'static str) -> Self {
        self.doc = doc;
        self
    }
    pub fn structural(mut self) -> Self {
        self.structural = true;
        self
    }
    /// Show the parameter only while the enumeration `key` is `value`.
    pub fn shown_when(mut self, key: &'static str, value: &'static str) -> Self {
        self.shown_when = Some((key, value));
        self
    }
    /// Whether the UI shows the parameter for these values ([`ParamSpec::shown_when`]).
    pub fn is_shown(&self, values: &ParamValues) -> bool {
        self.shown_when
            .is_none_or(|(key, value)| values.enumeration(key) == value)
    }

    pub fn default_value(&self) -> ParamValue {
        match &self.kind {
            ParamKind::Float { default, .. } => ParamValue::Float(*default),
            ParamKind::Int { default, .. } => ParamValue::Int(*default),
            ParamKind::Bool { default } => ParamValue::Bool(*default),
            ParamKind::Enum { options, default } => ParamValue::Enum(
                options
                    .get(*default)
                    .copied()
                    .unwrap_or_default()
                    .to_string(),
            ),
            ParamKind::Color { default } => ParamValue::Color(*default),
            ParamKind::Vec3 { default, .. } => ParamValue::Vec3(*default),
            ParamKind::Tf { default } => ParamValue::Tf(default.clone()),
            ParamKind::Tf2d { default } => ParamValue::Tf2d(default.clone()),
            ParamKind::Path { default } => ParamValue::Path(default.into()),
            ParamKind::Volume { .. } => ParamValue::Volume(String::new()),
        }
    }

    /// WGSL type of the uniform member, or None for non-uniform kinds.
    pub fn wgsl_type(&self) -> Option<&'static str> {
        match self.kind {
            ParamKind::Float { .. } => Some("f32"),
            ParamKind::Int { .. } => Some("i32"),
            ParamKind::Bool { .. } | ParamKind::Enum { .. } => Some("u32"),
            ParamKind::Color { .. } => Some("vec4<f32>"),
            ParamKind::Vec3 { .. } => Some("vec3<f32>"),
            ParamKind::Tf { .. }
            | ParamKind::Tf2d { .. }
            | ParamKind::Path { .. }
            | ParamKind::Volume { .. } => None,
        }
    }

    /// Checks a value against the spec; the message does not include the path.
    pub fn check(&self, v: &ParamValue) -> Result<(), String> {
        let range = |x: f32, min: f32, max: f32| {
            if !x.is_finite() {
                Err(format!("{x} is not finite"))
            } else if x < min || x > max {
                Err(format!("{x} is outside [{min}, {max}]"))
            } else {
                Ok(())
            }
        };
        match (&self.kind, v) {
            (ParamKind::Float { min, max, .. }, ParamValue::Float(x)) => range(*x, *min, *max),
            (ParamKind::Int { min, max, .. }, ParamValue::Int(x)) => {
                if x < min || x > max {
                    Err(format!("{x} is outside [{min}, {max}]"))
                } else {
                    Ok(())
                }
            }
            (ParamKind::Bool { .. }, ParamValue::Bool(_)) => Ok(()),
            (ParamKind::Enum { options, .. }, ParamValue::Enum(s)) => {
                if options.contains(&s.as_str()) {
                    Ok(())
                } else {
                    Err(format!("'{s}' is not one of {options:?}"))
                }
            }
            (ParamKind::Color { .. }, ParamValue::Color(c)) => {
                c.iter().try_for_each(|x| range(*x, 0.0, 1.0))
            }
            (ParamKind::Vec3 { min, max, .. }, ParamValue::Vec3(c)) => {
                c.iter().try_for_each(|x| range(*x, *min, *max))
            }
            (ParamKind::Tf { .. }, ParamValue::Tf(t)) => t.validate(),
            (ParamKind::Tf2d { .. }, ParamValue::Tf2d(t)) => t.validate(),
            (ParamKind::Path { .. }, ParamValue::Path(_)) => Ok(()),
            (ParamKind::Volume { .. }, ParamValue::Volume(name)) => {
                if name.is_empty() || valid_volume_name(name) {
                    Ok(())
                } else {
                    Err(format!(
                        "'{name}' is not a volume name (letters, digits and _, not starting with a digit)"
                    ))
                }
            }
            (_, v) => Err(format!(
                "expected {}, got {}",
                self.kind_name(),
                v.kind_name()
            )),
        }
    }

    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            ParamKind::Float { .. } => "a float",
            ParamKind::Int { .. } => "an int",
            ParamKind::Bool { .. } => "a bool",
            ParamKind::Enum { .. } => "an enum name",
            ParamKind::Color { .. } => "a colour (r, g, b, a)",
            ParamKind::Vec3 { .. } => "a vec3 (x, y, z)",
            ParamKind::Tf { .. } => "a transfer function",
            ParamKind::Tf2d { .. } => "a 2D transfer function",
            ParamKind::Path { .. } => "a file path string",
            ParamKind::Volume { .. } => "a volume name string",
        }
    }

    /// Parses a value from RON. Numbers are accepted for floats and ints, strings for
    /// enums, tuples/lists for colours and vectors, `(points: [...])` for TFs.
    pub fn from_ron(&self, value: &ron::Value) -> Result<ParamValue, String> {
        let v = match &self.kind {
            ParamKind::Float { .. } => ParamValue::Float(ron_f32(value)?),
            ParamKind::Int { .. } => {
                let x = ron_f32(value)?;
                if x.fract() != 0.0 {
                    return Err(format!("expected an int, got {x}"));
                }
                ParamValue::Int(x as i32)
            }
            ParamKind::Bool { .. } => match value {
                ron::Value::Bool(b) => ParamValue::Bool(*b),
                other => return Err(format!("expected a bool, got {}", describe_ron(other))),
            },
            ParamKind::Enum { .. } => match value {
                ron::Value::String(s) => ParamValue::Enum(s.clone()),
                other => {
                    return Err(format!(
                        "expected an enum name string, got {}",
                        describe_ron(other)
                    ));
                }
            },
            ParamKind::Color { .. } => {
                let xs = ron_list(value, 4)?;
                ParamValue::Color([xs[0], xs[1], xs[2], xs[3]])
            }
            ParamKind::Vec3 { .. } => {
                let xs = ron_list(value, 3)?;
                ParamValue::Vec3([xs[0], xs[1], xs[2]])
            }
            ParamKind::Tf { .. } => {
                let t: TfCurve = value
                    .clone()
                    .into_rust()
                    .map_err(|e| format!("expected a transfer function (points: [...]): {e}"))?;
                ParamValue::Tf(t)
            }
            ParamKind::Tf2d { .. } => {
                let t: crate::tf2d::Tf2d = value.clone().into_rust().map_err(|e| {
                    format!("expected a 2D transfer function (primitives: [...]): {e}")
                })?;
                ParamValue::Tf2d(t)
            }
            ParamKind::Path { .. } => match value {
                ron::Value::String(s) => ParamValue::Path(s.into()),
                other => {
                    return Err(format!(
                        "expected a file path string, got {}",
                        describe_ron(other)
                    ));
                }
            },
            ParamKind::Volume { .. } => match value {
                ron::Value::String(s) => ParamValue::Volume(s.clone()),
                other => {
                    return Err(format!(
                        "expected the name of one of the preset's volumes, got {}",
                        describe_ron(other)
                    ));
                }
            },
        };
        self.check(&v)?;
        Ok(v)
    }
}

/// Whether `name` can name a volume in a preset's `volumes:` (an identifier).
/// A volume name for a file ([`valid_volume_name`]): its stem without the volume
/// suffixes (`.nii.gz`, `.nrrd`…), other characters as `_`, prefixed by `v_` where it
/// would start with a digit; `volume` for an empty stem.
pub fn volume_name_for(path: &std::path::Path) -> String {
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = file.split('.').next().unwrap_or_default();
    let mut name: String = stem
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if name.is_empty() {
        name = "volume".into();
    }
    if !valid_volume_name(&name) {
        name = format!("v_{name}");
    }
    name
}

pub fn valid_volume_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

fn describe_ron(v: &ron::Value) -> String {
    let s = ron::to_string(v).unwrap_or_else(|_| format!("{v:?}"));
    if s.len() > 60 {
        format!("{}…", &s[..s.floor_char_boundary(60)])
    } else {
        s
    }
}

fn ron_f32(v: &ron::Value) -> Result<f32, String> {
    match v {
        ron::Value::Number(n) => Ok((*n).into_f64() as f32),
        other => Err(format!("expected a number, got {}", describe_ron(other))),
    }
}

fn ron_list(v: &ron::Value, n: usize) -> Result<Vec<f32>, String> {
    match v {
        ron::Value::Seq(items) if items.len() == n => items.iter().map(ron_f32).collect(),
        other => Err(format!("expected {n} numbers, got {}", describe_ron(other))),
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ParamValue {
    Float(f32),
    Int(i32),
    Bool(bool),
    Enum(String),
    Color([f32; 4]),
    Vec3([f32; 3]),
    Tf(TfCurve),
    Tf2d(crate::tf2d::Tf2d),
    Path(std::path::PathBuf),
    /// The name of a volume input (empty: the document's own volume).
    Volume(String),
}

impl ParamValue {
    pub fn kind_name(&self) -> &'static str {
        match self {
            ParamValue::Float(_) => "a float",
            ParamValue::Int(_) => "an int",
            ParamValue::Bool(_) => "a bool",
            ParamValue::Enum(_) => "an enum name",
            ParamValue::Color(_) => "a colour",
            ParamValue::Vec3(_) => "a vec3",
            ParamValue::Tf(_) => "a transfer function",
            ParamValue::Tf2d(_) => "a 2D transfer function",
            ParamValue::Path(_) => "a file path",
            ParamValue::Volume(_) => "a volume name",
        }
    }

    /// Feeds the value to a hasher (floats by their bits), for structure keys.
    pub fn hash_into(&self, h: &mut impl std::hash::Hasher) {
        use std::hash::Hash;
        std::mem::discriminant(self).hash(h);
        match self {
            ParamValue::Float(x) => x.to_bits().hash(h),
            ParamValue::Int(x) => x.hash(h),
            ParamValue::Bool(b) => b.hash(h),
            ParamValue::Enum(s) => s.hash(h),
            ParamValue::Color(c) => c.map(f32::to_bits).hash(h),
            ParamValue::Vec3(c) => c.map(f32::to_bits).hash(h),
            ParamValue::Path(p) => p.hash(h),
            ParamValue::Volume(name) => name.hash(h),
            // tables are never structural today; hash their RON text
            ParamValue::Tf(_) | ParamValue::Tf2d(_) => {
                ron::to_string(&self.to_ron()).unwrap_or_default().hash(h)
            }
        }
    }

    /// RON value as written in presets (plain numbers, strings, tuples).
    pub fn to_ron(&self) -> ron::Value {
        let num = |x: f32| ron::Value::Number(ron::Number::F32((x).into()));
        match self {
            ParamValue::Float(x) => num(*x),
            ParamValue::Int(x) => ron::Value::Number(ron::Number::I32(*x)),
            ParamValue::Bool(b) => ron::Value::Bool(*b),
            ParamValue::Enum(s) => ron::Value::String(s.clone()),
            ParamValue::Color(c) => ron::Value::Seq(c.iter().map(|x| num(*x)).collect()),
            ParamValue::Vec3(c) => ron::Value::Seq(c.iter().map(|x| num(*x)).collect()),
            ParamValue::Tf(t) => ron::to_string(t)
                .ok()
                .and_then(|s| ron::from_str(&s).ok())
                .unwrap_or(ron::Value::Unit),
            ParamValue::Tf2d(t) => ron::to_string(t)
                .ok()
                .and_then(|s| ron::from_str(&s).ok())
                .unwrap_or(ron::Value::Unit),
            ParamValue::Path(p) => ron::Value::String(p.display().to_string()),
            ParamValue::Volume(name) => ron::Value::String(name.clone()),
        }
    }
}

/// Values of all parameters of one plugin instance, by key.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParamValues {
    pub values: BTreeMap<String, ParamValue>,
}

impl ParamValues {
    pub fn defaults(specs: &[ParamSpec]) -> Self {
        Self {
            values: specs
                .iter()
                .map(|s| (s.key.to_string(), s.default_value()))
                .collect(),
        }
    }

    pub fn get(&self, key: &str) -> Option<&ParamValue> {
        self.values.get(key)
    }

    pub fn set(&mut self, key: &str, v: ParamValue) {
        self.values.insert(key.to_string(), v);
    }

    /// The value of `key` as a float (an int is converted).
    ///
    /// The typed accessors never hide a misspelt key or a wrong kind behind a default:
    /// in debug builds (every test) they panic naming the key, in release builds they
    /// log an error and return zero/false/empty.
    #[track_caller]
    pub fn float(&self, key: &str) -> f32 {
        match self.get(key) {
            Some(ParamValue::Float(x)) => *x,
            Some(ParamValue::Int(x)) => *x as f32,
            got => self.misread(key, "a float", got, 0.0),
        }
    }
    #[track_caller]
    pub fn int(&self, key: &str) -> i32 {
        match self.get(key) {
            Some(ParamValue::Int(x)) => *x,
            got => self.misread(key, "an int", got, 0),
        }
    }
    #[track_caller]
    pub fn boolean(&self, key: &str) -> bool {
        match self.get(key) {
            Some(ParamValue::Bool(b)) => *b,
            got => self.misread(key, "a bool", got, false),
        }
    }
    #[track_caller]
    pub fn enumeration(&self, key: &str) -> &str {
        match self.get(key) {
            Some(ParamValue::Enum(s)) => s,
            got => self.misread(key, "an enum name", got, ""),
        }
    }
    #[track_caller]
    pub fn color(&self, key: &str) -> [f32; 4] {
        match self.get(key) {
            Some(ParamValue::Color(c)) => *c,
            got => self.misread(key, "a colour", got, [0.0; 4]),
        }
    }
    #[track_caller]
    pub fn vec3(&self, key: &str) -> [f32; 3] {
        match self.get(key) {
            Some(ParamValue::Vec3(c)) => *c,
            got => self.misread(key, "a vec3", got, [0.0; 3]),
        }
    }
    #[track_caller]
    pub fn tf2d(&self, key: &str) -> Option<&crate::tf2d::Tf2d> {
        match self.get(key) {
            Some(ParamValue::Tf2d(t)) => Some(t),
            got => self.misread(key, "a 2D transfer function", got, None),
        }
    }
    /// A path parameter; None when empty.
    #[track_caller]
    pub fn path(&self, key: &str) -> Option<&std::path::Path> {
        match self.get(key) {
            Some(ParamValue::Path(p)) => (!p.as_os_str().is_empty()).then_some(p.as_path()),
            got => self.misread(key, "a file path", got, None),
        }
    }
    /// A volume input's name; empty for the document's own volume.
    #[track_caller]
    pub fn volume(&self, key: &str) -> &str {
        match self.get(key) {
            Some(ParamValue::Volume(name)) => name,
            got => self.misread(key, "a volume name", got, ""),
        }
    }
    #[track_caller]
    pub fn tf(&self, key: &str) -> Option<&TfCurve> {
        match self.get(key) {
            Some(ParamValue::Tf(t)) => Some(t),
            got => self.misread(key, "a transfer function", got, None),
        }
    }

    /// A read of an absent key or of the wrong kind: a programming error (a misspelt
    /// key), so debug builds panic; release builds log it and go on with `fallback`.
    #[track_caller]
    fn misread<T>(&self, key: &str, want: &str, got: Option<&ParamValue>, fallback: T) -> T {
        let what = match got {
            None => {
                let known: Vec<&str> = self.values.keys().map(String::as_str).collect();
                format!("there is no such parameter (known: {})", known.join(", "))
            }
            Some(v) => format!("it holds {}", v.kind_name()),
        };
        let message = format!("parameter '{key}' read as {want}, but {what}");
        if cfg!(debug_assertions) {
            panic!("{message}");
        }
        log::error!("{message}");
        fallback
    }
}

/// One member of a generated uniform struct.
#[derive(Debug, Clone, PartialEq)]
pub struct UniformMember {
    pub key: &'static str,
    pub wgsl_type: &'static str,
    pub offset: u32,
    pub size: u32,
}

/// Layout of the uniform struct generated from a spec.
#[derive(Debug, Clone, PartialEq)]
pub struct UniformLayout {
    pub members: Vec<UniformMember>,
    /// Size in bytes, a multiple of 16, at least 16.
    pub size: u32,
}

impl UniformLayout {
    pub fn new(specs: &[ParamSpec]) -> Self {
        let mut members = Vec::new();
        let mut offset = 0u32;
        for s in specs {
            let Some(ty) = s.wgsl_type() else { continue };
            let (align, size) = match ty {
                "vec4<f32>" => (16, 16),
                "vec3<f32>" => (16, 12),
                _ => (4, 4),
            };
            offset = offset.div_ceil(align) * align;
            members.push(UniformMember {
                key: s.key,
                wgsl_type: ty,
                offset,
                size,
            });
            offset += size;
        }
        let size = offset.div_ceil(16).max(1) * 16;
        Self { members, size }
    }

    /// WGSL struct declaration named `name`.
    pub fn wgsl(&self, name: &str) -> String {
        let mut s = format!("struct {name} {{\n");
        if self.members.is_empty() {
            s.push_str("    unused: u32,\n");
        }
        for m in &self.members {
            s.push_str(&format!("    {}: {},\n", m.key, m.wgsl_type));
        }
        s.push('}');
        s
    }

    /// Packs values (missing ones as defaults) into uniform bytes.
    pub fn pack(&self, specs: &[ParamSpec], values: &ParamValues) -> Vec<u8> {
        let mut out = vec![0u8; self.size as usize];
        for m in &self.members {
            let spec = specs.iter().find(|s| s.key == m.key);
            let v = values
                .get(m.key)
                .cloned()
                .or_else(|| spec.map(|s| s.default_value()));
            let o = m.offset as usize;
            let mut put =
                |i: usize, bytes: [u8; 4]| out[o + 4 * i..o + 4 * i + 4].copy_from_slice(&bytes);
            match (v, spec.map(|s| &s.kind)) {
                (Some(ParamValue::Float(x)), _) => put(0, x.to_le_bytes()),
                (Some(ParamValue::Int(x)), _) => put(0, x.to_le_bytes()),
                (Some(ParamValue::Bool(b)), _) => put(0, (b as u32).to_le_bytes()),
                (Some(ParamValue::Enum(e)), Some(ParamKind::Enum { options, .. })) => {
                    let idx = options.iter().position(|o| *o == e).unwrap_or(0) as u32;
                    put(0, idx.to_le_bytes())
                }
                (Some(ParamValue::Color(c)), _) => {
                    for (i, x) in c.iter().enumerate() {
                        put(i, x.to_le_bytes());
                    }
                }
                (Some(ParamValue::Vec3(c)), _) => {
                    for (i, x) in c.iter().enumerate() {
                        put(i, x.to_le_bytes());
                    }
                }
                _ => {}
            }
        }
        out
    }
}

/// A lowercase identifier: a lowercase ASCII letter, then lowercase letters, digits
/// and `_` (parameter keys, plugin and probe names, probe figures).
pub fn lowercase_ident(s: &str) -> bool {
    s.chars().next().is_some_and(|c| c.is_ascii_lowercase())
        && s.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

/// Checks that a plugin's specs are well formed (unique identifier keys, defaults valid).
pub fn validate_specs(specs: &[ParamSpec]) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    for s in specs {
        if !lowercase_ident(s.key) {
            return Err(format!(
                "parameter key '{}' must be a lowercase identifier",
                s.key
            ));
        }
        if !seen.insert(s.key) {
            return Err(format!("parameter key '{}' is declared twice", s.key));
        }
        if let ParamKind::Float { min, log: true, .. } = s.kind
            && min <= 0.0
        {
            return Err(format!(
                "parameter '{}' is logarithmic but its minimum {min} is not > 0",
                s.key
            ));
        }
        s.check(&s.default_value())
            .map_err(|e| format!("parameter '{}' default: {e}", s.key))?;
        if let Some(e) = s.element {
            check_element(specs, s, e)?;
        }
        if let Some((key, value)) = s.shown_when {
            let names_a_value = specs.iter().any(|o| {
                o.key == key
                    && matches!(&o.kind, ParamKind::Enum { options, .. } if options.contains(&value))
            });
            if !names_a_value {
                return Err(format!(
                    "parameter '{}' is shown when '{key}' is '{value}', but '{key}' is not an enumeration with that value",
                    s.key
                ));
            }
        }
    }
    Ok(())
}

/// A group's element is one run of specs, its switch is among its members (a bool, an
/// enumeration with "off" first or an int from −1), and its limit an int parameter
/// outside it.
fn check_element(specs: &[ParamSpec], s: &ParamSpec, e: Element) -> Result<(), String> {
    let Element { group: g, index } = e;
    if index >= g.count {
        return Err(format!(
            "parameter '{}' is element {index} of group '{}', which has {}",
            s.key, g.name, g.count
        ));
    }
    let run: Vec<usize> = specs
        .iter()
        .enumerate()
        .filter(|(_, o)| o.element == Some(e))
        .map(|(i, _)| i)
        .collect();
    if run.windows(2).any(|w| w[1] != w[0] + 1) {
        return Err(format!(
            "group '{}' element {index}: its parameters are not declared together",
            g.name
        ));
    }
    if let Some(template) = g.switch {
        let key = indexed(template, index);
        let ok = specs.iter().any(|o| {
            o.key == key
                && o.element == Some(e)
                && match &o.kind {
                    ParamKind::Bool { .. } => true,
                    ParamKind::Enum { options, .. } => options.first() == Some(&"off"),
                    ParamKind::Int { min, .. } => *min == -1,
                    _ => false,
                }
        });
        if !ok {
            return Err(format!(
                "group '{}' element {index}: its switch '{key}' is not among its parameters as a bool, an enumeration starting with \"off\" or an int from −1",
                g.name
            ));
        }
    }
    if let Some(limit) = g.limit
        && !specs.iter().any(|o| {
            o.key == limit && o.element.is_none() && matches!(o.kind, ParamKind::Int { .. })
        })
    {
        return Err(format!(
            "group '{}': its limit '{limit}' is not an int parameter outside the group",
            g.name
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group_members_split_around_their_index() {
        assert_eq!(split_member("shape0_kind", 0), Some(("shape", "kind")));
        assert_eq!(split_member("light12_dir", 12), Some(("light", "dir")));
        assert_eq!(split_member("iso2", 2), Some(("iso", "")));
        // the index, not another digit run: "l1" + "1" in "l11_x"? no: 11 is one run
        assert_eq!(split_member("l11_x", 1), None);
        assert_eq!(split_member("rgb2_1_tf", 1), Some(("rgb2_", "tf")));
    }

    /// A group written as a list becomes its flat keys; a scalar group is a list of
    /// values; a plain Vec3 parameter named like a list keeps its value; errors name
    /// the element and the cause.
    #[test]
    fn groups_written_as_lists_become_flat_keys() {
        const G: Group = Group::new("Shape", 3).switch("shape{}_kind");
        const ISO: Group = Group::new("Iso", 2);
        let mut specs = G.specs(|i| {
            vec![
                ParamSpec::enumeration(G.key("shape{}_kind", i), "Kind", &["off", "box"], 0),
                ParamSpec::vec3(G.key("shape{}_center", i), "Centre", -1.0, 1.0, [0.0; 3]),
            ]
        });
        specs.extend(
            ISO.specs(|i| vec![ParamSpec::float(ISO.key("iso{}", i), "Iso", 0.0, 1.0, 0.5)]),
        );
        let parse_with = |specs: &[ParamSpec], text: &str| {
            let map: std::collections::BTreeMap<String, ron::Value> = ron::from_str(text).unwrap();
            flatten_groups(specs, &map)
        };
        let parse = |text: &str| parse_with(&specs, text);
        let flat = parse(
            r#"{"shape": [(kind: "box"), (kind: "box", center: (0.1, 0.2, 0.3))], "iso": [0.25]}"#,
        )
        .unwrap();
        let keys: Vec<&str> = flat.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            keys,
            ["iso0", "shape0_kind", "shape1_center", "shape1_kind"]
        );
        for (k, v) in &flat {
            let spec = specs.iter().find(|s| s.key == k).unwrap();
            spec.from_ron(v).unwrap();
        }
        let err = |text: &str| parse(text).unwrap_err();
        assert_eq!(err(r#"{"iso": [0.1, 0.2, 0.3]}"#).0, "iso");
        let (at, why) = err(r#"{"shape": [(kind: "box"), (knd: "box")]}"#);
        assert_eq!(at, "shape[1]");
        assert!(
            why.contains("unknown field 'knd'") && why.contains("center, kind"),
            "{why}"
        );
        assert!(
            err(r#"{"shape": [(kind: "box")], "shape0_kind": "off"}"#)
                .1
                .contains("also given")
        );
        assert!(err(r#"{"shape": [0.5]}"#).1.contains("map of its fields"));
        // saved back: one list per group, ending at its last given element; a value
        // list writes an element left out of the middle with its default
        let given: std::collections::BTreeMap<String, ron::Value> = flat.into_iter().collect();
        let lists = group_flat_keys(&specs, given.clone());
        assert_eq!(
            lists.keys().map(String::as_str).collect::<Vec<_>>(),
            ["iso", "shape"]
        );
        let back: std::collections::BTreeMap<String, ron::Value> = flatten_groups(&specs, &lists)
            .unwrap()
            .into_iter()
            .collect();
        assert_eq!(back, given);
        let mut second: std::collections::BTreeMap<String, ron::Value> = Default::default();
        second.insert(
            "iso1".into(),
            ron::Value::Number(ron::Number::F32(0.75.into())),
        );
        second.insert("other".into(), ron::Value::Bool(true));
        let lists = group_flat_keys(&specs, second);
        assert_eq!(
            ron::to_string(&lists["iso"]).unwrap(),
            ron::to_string(&ron::Value::Seq(vec![
                ron::Value::Number(ron::Number::F32(0.5.into())),
                ron::Value::Number(ron::Number::F32(0.75.into())),
            ]))
            .unwrap()
        );
        assert_eq!(lists["other"], ron::Value::Bool(true));
        // a plain parameter of that name is not a list
        let mut plain = specs.clone();
        plain.push(ParamSpec::vec3("shape", "Plain", -1.0, 1.0, [0.0; 3]));
        let flat = parse_with(&plain, r#"{"shape": (0.1, 0.2, 0.3)}"#).unwrap();
        assert_eq!(flat[0].0, "shape");
    }

    #[test]
    fn a_group_makes_flat_keys_and_knows_its_elements_in_use() {
        let lights = Group::new("Light", 3).switch("l{}_on");
        let mut specs = vec![ParamSpec::int("count", "Count", 0, 3, 2)];
        specs.extend(lights.specs(|i| {
            vec![
                ParamSpec::boolean(lights.key("l{}_on", i), "on", i == 0),
                ParamSpec::float(lights.key("l{}_power", i), "power", 0.0, 1.0, 0.5),
            ]
        }));
        validate_specs(&specs).unwrap();
        let keys: Vec<&str> = specs.iter().map(|s| s.key).collect();
        assert_eq!(
            keys,
            [
                "count", "l0_on", "l0_power", "l1_on", "l1_power", "l2_on", "l2_power"
            ]
        );
        // the same key is the same allocation, however often it is made
        assert!(std::ptr::eq(lights.key("l{}_on", 1), specs[3].key));
        let mut values = ParamValues::defaults(&specs);
        assert!(lights.is_on(0, &values) && !lights.is_on(1, &values));
        values.set("l1_on", ParamValue::Bool(true));
        assert!(lights.is_on(1, &values));
        // the uniform layout is that of the flat parameters
        assert!(
            UniformLayout::new(&specs)
                .wgsl("P")
                .contains("l2_power: f32")
        );
        let limited = Group::new("Iso", 3).limit("count");
        let mut iso = vec![ParamSpec::int("count", "Count", 0, 3, 2)];
        iso.extend(isovalues(limited));
        validate_specs(&iso).unwrap();
        let values = ParamValues::defaults(&iso);
        assert!(limited.in_use(1, &values) && !limited.in_use(2, &values));
    }

    /// A group of one float member per element, `iso{}`.
    fn isovalues(g: Group) -> Vec<ParamSpec> {
        g.specs(|i| vec![ParamSpec::float(g.key("iso{}", i), "v", 0.0, 1.0, 0.5)])
    }

    #[test]
    fn a_malformed_group_is_refused_naming_it() {
        let g = Group::new("Light", 2).switch("l{}_on");
        // the switch is a float
        let specs = g.specs(|i| vec![ParamSpec::float(g.key("l{}_on", i), "on", 0.0, 1.0, 1.0)]);
        let e = validate_specs(&specs).unwrap_err();
        assert!(
            e.contains("group 'Light' element 0: its switch 'l0_on'"),
            "{e}"
        );
        // an element split by another parameter
        let plain = Group::new("Light", 2);
        let mut specs = plain.specs(|i| {
            vec![
                ParamSpec::float(plain.key("a{}", i), "a", 0.0, 1.0, 1.0),
                ParamSpec::float(plain.key("b{}", i), "b", 0.0, 1.0, 1.0),
            ]
        });
        specs.insert(1, ParamSpec::float("x", "x", 0.0, 1.0, 1.0));
        let e = validate_specs(&specs).unwrap_err();
        assert!(e.contains("not declared together"), "{e}");
        // a limit that names nothing
        let specs = isovalues(Group::new("Iso", 2).limit("count"));
        let e = validate_specs(&specs).unwrap_err();
        assert!(e.contains("its limit 'count'"), "{e}");
    }

    #[test]
    fn a_mode_parameter_is_shown_only_in_its_mode() {
        let mut specs = specs();
        specs.push(ParamSpec::float("k", "K", 0.0, 1.0, 0.5).shown_when("mode", "x"));
        assert!(validate_specs(&specs).is_ok());
        let mut values = ParamValues::defaults(&specs);
        assert!(!specs[7].is_shown(&values));
        values.set("mode", ParamValue::Enum("x".into()));
        assert!(specs[7].is_shown(&values) && specs[0].is_shown(&values));
        for bad in [("mode", "z"), ("a", "x"), ("none", "x")] {
            specs[7] = ParamSpec::float("k", "K", 0.0, 1.0, 0.5).shown_when(bad.0, bad.1);
            let e = validate_specs(&specs).unwrap_err();
            assert!(e.contains("'k' is shown when"), "{e}");
        }
    }

    fn specs() -> Vec<ParamSpec> {
        vec![
            ParamSpec::float("a", "A", 0.0, 1.0, 0.5),
            ParamSpec::vec3("dir", "Dir", -1.0, 1.0, [0.0, 1.0, 0.0]),
            ParamSpec::boolean("on", "On", true),
            ParamSpec::color("tint", "Tint", [1.0, 0.0, 0.0, 1.0]),
            ParamSpec::enumeration("mode", "Mode", &["x", "y"], 1),
            ParamSpec::tf("tf", "TF", TfCurve::ramp(0.0, 1.0, [1.0; 4])),
            ParamSpec::int("n", "N", 1, 13, 4),
        ]
    }

    #[test]
    #[should_panic(
        expected = "parameter 'mdoe' read as an enum name, but there is no such parameter"
    )]
    fn a_misspelt_key_is_an_error_not_a_default() {
        ParamValues::defaults(&specs()).enumeration("mdoe");
    }

    #[test]
    #[should_panic(expected = "parameter 'on' read as a float, but it holds a bool")]
    fn a_read_of_the_wrong_kind_is_an_error() {
        ParamValues::defaults(&specs()).float("on");
    }

    #[test]
    fn layout_follows_wgsl_rules() {
        let l = UniformLayout::new(&specs());
        let offs: Vec<(&str, u32)> = l.members.iter().map(|m| (m.key, m.offset)).collect();
        assert_eq!(
            offs,
            vec![
                ("a", 0),
                ("dir", 16),
                ("on", 28),
                ("tint", 32),
                ("mode", 48),
                ("n", 52)
            ]
        );
        assert_eq!(l.size, 64);
    }

    #[test]
    fn layout_matches_naga() {
        let l = UniformLayout::new(&specs());
        let src = format!(
            "{}\n@group(0) @binding(0) var<uniform> u: P;\n@fragment fn f() -> @location(0) vec4<f32> {{ return vec4<f32>(u.a); }}",
            l.wgsl("P")
        );
        let module = naga::front::wgsl::parse_str(&src).unwrap();
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("P"))
            .unwrap();
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("not a struct")
        };
        for (m, n) in l.members.iter().zip(members) {
            assert_eq!(Some(m.key), n.name.as_deref());
            assert_eq!(m.offset, n.offset, "member {}", m.key);
        }
        assert_eq!(l.size, span.div_ceil(16) * 16);
    }

    #[test]
    fn pack_writes_values_at_offsets() {
        let s = specs();
        let l = UniformLayout::new(&s);
        let mut v = ParamValues::defaults(&s);
        v.set("a", ParamValue::Float(0.25));
        let b = l.pack(&s, &v);
        assert_eq!(f32::from_le_bytes(b[0..4].try_into().unwrap()), 0.25);
        assert_eq!(f32::from_le_bytes(b[20..24].try_into().unwrap()), 1.0);
        assert_eq!(u32::from_le_bytes(b[28..32].try_into().unwrap()), 1);
        assert_eq!(u32::from_le_bytes(b[48..52].try_into().unwrap()), 1);
        assert_eq!(i32::from_le_bytes(b[52..56].try_into().unwrap()), 4);
    }

    #[test]
    fn ron_values_are_checked() {
        let s = specs();
        let a = &s[0];
        assert_eq!(
            a.from_ron(&ron::from_str("0.75").unwrap()),
            Ok(ParamValue::Float(0.75))
        );
        assert!(
            a.from_ron(&ron::from_str("2.0").unwrap())
                .unwrap_err()
                .contains("outside")
        );
        assert!(
            a.from_ron(&ron::from_str("\"x\"").unwrap())
                .unwrap_err()
                .contains("number")
        );
        let m = &s[4];
        assert!(m.from_ron(&ron::from_str("\"z\"").unwrap()).is_err());
        let tf = &s[5];
        let v = tf
            .from_ron(
                &ron::from_str(
                    "(points: [(x: 0.0, color: (0,0,0,0)), (x: 1.0, color: (1,1,1,1))])",
                )
                .unwrap(),
            )
            .unwrap();
        assert!(matches!(v, ParamValue::Tf(_)));
        // round trip through to_ron
        for spec in &s {
            let d = spec.default_value();
            assert_eq!(spec.from_ron(&d.to_ron()).unwrap(), d, "{}", spec.key);
        }
    }

    #[test]
    fn specs_are_validated() {
        assert!(validate_specs(&specs()).is_ok());
        let mut bad = specs();
        bad.push(ParamSpec::float("a", "A again", 0.0, 1.0, 0.5));
        assert!(validate_specs(&bad).unwrap_err().contains("twice"));
        assert!(validate_specs(&[ParamSpec::float("B", "b", 0.0, 1.0, 0.5)]).is_err());
        assert!(validate_specs(&[ParamSpec::float_log("l", "l", 0.0, 1.0, 0.5)]).is_err());
        assert!(validate_specs(&[ParamSpec::float("l", "l", 0.0, 1.0, 5.0)]).is_err());
    }
}
