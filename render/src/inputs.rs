//! Named volume inputs: the volumes a document names beside its own (`volumes:` in a
//! preset), each with its own grid, spacing and components.
//!
//! A plugin declares an input as a parameter of kind [`ParamKind::Volume`]
//! ([`crate::params::ParamSpec::volume`]): its value names one of the document's
//! volumes, or is empty for the document's own volume. The GPU and the CPU twin read the
//! same volume ([`crate::plugin::GpuInit::input`], [`crate::plugin::CpuContext::input`]),
//! with its components as loaded (a vector field is not reduced to its magnitude).
//!
//! *Choice:* every input spans the document volume's box: texture coordinate t of the
//! document's volume is texture coordinate t of the input, whatever the input's grid
//! (a coarser field, a finer label volume). Inputs that cover another physical extent
//! must be resampled before; none of the loaders carries an origin that would place
//! them.
//!
//! The renderer recreates an instance's resources and reruns its passes exactly when
//! the volume one of its inputs resolves to changes (another name, or another volume
//! under the same name); a volume set again under the same name and the same `Arc` is
//! no change ([`crate::Renderer::set_inputs`]).

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::params::{ParamKind, ParamSpec, ParamValues};
use crate::volume::Volume;

/// The named volumes of a document (not its own volume).
#[derive(Debug, Clone, Default)]
pub struct VolumeInputs {
    named: BTreeMap<String, Arc<Volume>>,
}

/// Which volume each of an instance's inputs resolves to: (key, the name, the volume's
/// address: 0 for the document's own volume or a name the document lacks). Two equal
/// stamps mean the same volumes.
pub type InputStamp = Vec<(&'static str, String, usize)>;

/// The document's volumes as a plugin's promises see them ([`crate::plugin::Plugin::
/// transparency`], [`crate::plugin::Plugin::region`]): its own volume and its named
/// ones, through which a plugin's volume inputs resolve.
#[derive(Debug, Clone, Copy)]
pub struct Volumes<'a> {
    pub main: &'a Volume,
    pub named: &'a VolumeInputs,
}

impl<'a> Volumes<'a> {
    pub fn new(main: &'a Volume, named: &'a VolumeInputs) -> Self {
        Self { main, named }
    }

    /// The document's own volume and no named ones.
    pub fn of(main: &'a Volume) -> Self {
        Self::new(main, VolumeInputs::empty())
    }

    /// The volume the input `key` of `params` names ([`VolumeInputs::resolve`]).
    pub fn input(&self, params: &ParamValues, key: &str) -> Result<&'a Volume, String> {
        self.named.resolve(self.main, params, key)
    }
}

impl VolumeInputs {
    pub fn new(named: BTreeMap<String, Arc<Volume>>) -> Self {
        Self { named }
    }

    /// No named volumes.
    pub fn empty() -> &'static Self {
        static EMPTY: std::sync::OnceLock<VolumeInputs> = std::sync::OnceLock::new();
        EMPTY.get_or_init(Self::default)
    }

    pub fn insert(&mut self, name: &str, volume: Arc<Volume>) {
        self.named.insert(name.to_string(), volume);
    }

    pub fn get(&self, name: &str) -> Option<&Arc<Volume>> {
        self.named.get(name)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.named.keys().map(String::as_str)
    }

    pub fn is_empty(&self) -> bool {
        self.named.is_empty()
    }

    /// The volume input `key` of `params` names: `main` for an empty name. An error
    /// message (without the plugin's id) for a name the document does not have.
    pub fn resolve<'a>(
        &'a self,
        main: &'a Volume,
        params: &ParamValues,
        key: &str,
    ) -> Result<&'a Volume, String> {
        let name = params.volume(key);
        if name.is_empty() {
            return Ok(main);
        }
        self.get(name).map(|v| v.as_ref()).ok_or_else(|| {
            let known: Vec<&str> = self.names().collect();
            format!(
                "{key}: there is no volume named '{name}' (the document's volumes: {})",
                if known.is_empty() {
                    "none".to_string()
                } else {
                    known.join(", ")
                }
            )
        })
    }

    /// Checks every volume input of `specs` in `params`: the name exists and the
    /// volume has the components the input asks for.
    pub fn check(
        &self,
        main: &Volume,
        specs: &[ParamSpec],
        params: &ParamValues,
    ) -> Result<(), String> {
        for spec in specs {
            let ParamKind::Volume { components } = spec.kind else {
                continue;
            };
            let v = self.resolve(main, params, spec.key)?;
            if !components.admits(v.components) {
                let name = params.volume(spec.key);
                return Err(format!(
                    "{}: the volume {} has {} component{}, but the input needs {}",
                    spec.key,
                    if name.is_empty() {
                        format!("'{}' (the document's own)", v.name)
                    } else {
                        format!("'{name}'")
                    },
                    v.components,
                    if v.components == 1 { "" } else { "s" },
                    components.describe()
                ));
            }
        }
        Ok(())
    }

    /// Which volumes the inputs of `specs` in `params` resolve to ([`InputStamp`]).
    pub fn stamp(&self, specs: &[ParamSpec], params: &ParamValues) -> InputStamp {
        specs
            .iter()
            .filter(|s| matches!(s.kind, ParamKind::Volume { .. }))
            .map(|s| {
                let name = params.volume(s.key);
                let at = self.get(name).map_or(0, |v| Arc::as_ptr(v) as usize);
                (s.key, name.to_string(), at)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{Components, ParamValue};

    fn vector(name: &str) -> Arc<Volume> {
        let field = crate::flow::AnalyticField {
            field: crate::flow::AnalyticKind::Rotation,
            size: [4, 4, 4],
        };
        let mut v = field.volume().unwrap();
        v.name = name.into();
        Arc::new(v)
    }

    #[test]
    fn inputs_resolve_by_name_and_check_their_components() {
        let main = crate::volume::demo();
        let mut inputs = VolumeInputs::default();
        inputs.insert("wind", vector("wind"));
        let specs = vec![ParamSpec::volume("field", "Field", Components::Vector)];
        let mut p = ParamValues::defaults(&specs);
        // the default is the document's own volume, here a scalar one: refused
        assert!(std::ptr::eq(
            inputs.resolve(&main, &p, "field").unwrap(),
            &main
        ));
        let e = inputs.check(&main, &specs, &p).unwrap_err();
        assert!(e.contains("has 1 component") && e.contains("vector"), "{e}");
        p.set("field", ParamValue::Volume("wind".into()));
        inputs.check(&main, &specs, &p).unwrap();
        assert_eq!(inputs.resolve(&main, &p, "field").unwrap().components, 3);
        let stamp = inputs.stamp(&specs, &p);
        assert_ne!(stamp[0].2, 0);
        // the same volume under the name again: the same stamp; another volume: not
        let mut again = inputs.clone();
        assert_eq!(again.stamp(&specs, &p), stamp);
        again.insert("wind", vector("wind"));
        assert_ne!(again.stamp(&specs, &p), stamp);
        p.set("field", ParamValue::Volume("gust".into()));
        let e = inputs.check(&main, &specs, &p).unwrap_err();
        assert!(
            e.contains("no volume named 'gust'") && e.contains("wind"),
            "{e}"
        );
    }
}
