//! `classify.tf1d`: a transfer function over the normalised scalar (the model of
//! [`vwb_render::tf`]: control points, primitives, logarithmic opacity axis), baked
//! into a lookup table, in three modes (Rezk-Salama 2001 §2–3; Engel et al. 2001):
//!
//! - `post` (post-classification): interpolate the scalar, then look it up
//!   (`tf1d.wgsl`).
//! - `pre` (pre-classification): a pre-pass classifies every voxel into an
//!   opacity-weighted RGBA volume (`tf1d_prepass.wgsl`, rgba16float, rerun only when
//!   the TF changes), which the sampler interpolates (`tf1d_pre.wgsl`).
//! - `preintegrated`: a 256×256 table over (front, back) values for the current slice
//!   spacing (`preint.rs`, `tf1d_preint.wgsl`), rebuilt only when the TF, the opacity
//!   scale or the spacing changes.
//!
//! Parameters: `mode`, `tf` (the curve), `opacity` (a global opacity scale, clamped
//! to 1 per reference step), `shade_at` (pre-integrated only: where the shading
//! plugins read the gradient, at the front sample or at the slab's opacity centroid,
//! a second 256×256 table; see [`preint`]). The CPU twins evaluate the same baked tables with the
//! same filtering as the GPU samplers.

pub mod preint;
pub mod probes;

use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, GpuInit, GpuResource, Plugin, PluginError, PrepassDecl,
    ResourceDecl, ResourceKind, ShaderSource, StorageFormat, Transparency, Volumes,
};
use vwb_render::tf::{LUT_SIZE, TfCurve, TfPoint, eval_lut};

#[cfg(test)]
mod tests;

/// Classification mode (the `mode` parameter; structural: it changes the code, the
/// resources and the pre-pass).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Interpolate the scalar, then classify.
    #[default]
    Post,
    /// Classify the voxels in a pre-pass, then interpolate the opacity-weighted colours.
    Pre,
    /// Classify the slab between two slices from a pre-integrated table.
    Preintegrated,
}

impl Mode {
    pub const NAMES: [&'static str; 3] = ["post", "pre", "preintegrated"];

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    pub fn from_name(name: &str) -> Option<Self> {
        [Mode::Post, Mode::Pre, Mode::Preintegrated]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// Values of the `shade_at` parameter.
pub const SHADE_AT: [&str; 2] = ["front", "centroid"];

/// The plugin, configured for one mode (the registry holds the post-classification
/// one; [`Plugin::configure`] picks the others).
#[derive(Debug, Clone, Copy, Default)]
pub struct Tf1d {
    pub mode: Mode,
    /// `shade_at: centroid` (structural: at `front` the code that moves the shading
    /// point is left out, so that a shading plugin reads its gradient at the sample's
    /// own point, in the fetch that gives the sample its value where the gradients are
    /// precomputed; docs/perf.md, "One fetch for the value and the gradient").
    pub centroid: bool,
}

/// The default curve: soft tissue faint, dense matter bright.
pub fn default_curve() -> TfCurve {
    TfCurve::new(vec![
        TfPoint {
            x: 0.0,
            color: [0.0, 0.0, 0.0, 0.0],
        },
        TfPoint {
            x: 0.25,
            color: [0.8, 0.4, 0.3, 0.0],
        },
        TfPoint {
            x: 0.45,
            color: [0.9, 0.6, 0.5, 0.08],
        },
        TfPoint {
            x: 1.0,
            color: [1.0, 1.0, 0.95, 0.6],
        },
    ])
}

fn curve(params: &ParamValues) -> TfCurve {
    params.tf("tf").cloned().unwrap_or_else(default_curve)
}

impl Plugin for Tf1d {
    fn id(&self) -> &'static str {
        "classify.tf1d"
    }
    /// The pre-integration table's rebuild and the TF suggestion, on the CPU
    /// ([`probes`]).
    fn probes(&self) -> Vec<Arc<dyn vwb_render::plugin::Probe>> {
        vec![Arc::new(probes::PreintTable), Arc::new(probes::Suggest)]
    }
    fn display_name(&self) -> &'static str {
        "1D transfer function"
    }
    fn description(&self) -> &'static str {
        "Transfer function over the scalar: post-, pre- or pre-integrated classification"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![
            ParamSpec::enumeration("mode", "Mode", &Mode::NAMES, 0)
                .structural()
                .with_doc("when the transfer function is applied. post: the data are interpolated between voxels, then coloured (sharp; the default). pre: each voxel is coloured, then the colours are interpolated (cheaper, blurs thin features). preintegrated: the colour and opacity of the whole slab between two slices is looked up (fewest slice rings at coarse spacing where boundaries are wider than the spacing; structures thinner than the spacing still band, and there it can be less accurate than post)"),
            ParamSpec::tf("tf", "Transfer function", default_curve())
                .with_doc("control points over the normalised value [0,1]"),
            ParamSpec::float_log("opacity", "Opacity scale", 0.01, 100.0, 1.0)
                .with_doc("multiplies every opacity (per reference step, clamped to 1)"),
            ParamSpec::enumeration("shade_at", "Shade at", &SHADE_AT, 0)
                .structural()
                .shown_when("mode", "preintegrated")
                .with_doc("preintegrated mode only: where a shading plugin reads the gradient. front: at the slice sample (Engel et al. 2001). centroid: inside the slab, where its opacity is taken up (fewer rings on lit surfaces at coarse spacing)"),
        ]
    }
    fn shader(&self) -> ShaderSource {
        match self.mode {
            Mode::Post => ShaderSource::new_static(
                "plugins/src/classify_tf1d/tf1d.wgsl",
                include_str!("tf1d.wgsl"),
            ),
            Mode::Pre => ShaderSource::new_static(
                "plugins/src/classify_tf1d/tf1d_pre.wgsl",
                include_str!("tf1d_pre.wgsl"),
            ),
            Mode::Preintegrated if self.centroid => ShaderSource::new_static(
                "plugins/src/classify_tf1d/tf1d_preint.wgsl",
                include_str!("tf1d_preint.wgsl"),
            ),
            Mode::Preintegrated => ShaderSource::without_region(
                "plugins/src/classify_tf1d/tf1d_preint.wgsl",
                include_str!("tf1d_preint.wgsl"),
                "centroid",
                "",
            ),
        }
    }
    fn resources(&self) -> Vec<ResourceDecl> {
        let name = match self.mode {
            Mode::Post | Mode::Pre => "lut",
            Mode::Preintegrated => "preint",
        };
        let mut decls = vec![ResourceDecl {
            name,
            kind: if self.mode == Mode::Preintegrated {
                ResourceKind::Texture2d
            } else {
                ResourceKind::Texture1d
            },
        }];
        if self.mode == Mode::Preintegrated {
            decls.push(ResourceDecl {
                name: "preint_depth",
                kind: ResourceKind::Texture2d,
            });
        }
        decls
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        (self.mode == Mode::Pre).then(|| PrepassDecl {
            target: "classified",
            format: StorageFormat::Rgba16Float,
            scale: 1.0,
            shader: ShaderSource::new_static(
                "plugins/src/classify_tf1d/tf1d_prepass.wgsl",
                include_str!("tf1d_prepass.wgsl"),
            ),
            depends_on: vec!["tf"],
            holds_value: false,
        })
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let mode = Mode::from_name(params.enumeration("mode")).unwrap_or_default();
        let centroid = params.enumeration("shade_at") == SHADE_AT[1];
        (mode != self.mode || centroid != self.centroid)
            .then(|| Arc::new(Tf1d { mode, centroid }) as Arc<dyn Plugin>)
    }
    fn uses_slice_spacing(&self) -> bool {
        self.mode == Mode::Preintegrated
    }
    fn create_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
    ) -> Result<Vec<GpuResource>, PluginError> {
        let n = LUT_SIZE as u32;
        let res = match self.mode {
            Mode::Post | Mode::Pre => vec![gpu.create_table_1d("classify.tf1d lut", n)],
            Mode::Preintegrated => vec![
                gpu.create_sample_table("classify.tf1d pre-integration table", n, n),
                gpu.create_sample_table("classify.tf1d pre-integration centroids", n, n),
            ],
        };
        self.update_resources(gpu, params, &res)?;
        Ok(res)
    }
    fn update_resources(
        &self,
        gpu: &GpuInit,
        params: &ParamValues,
        resources: &[GpuResource],
    ) -> Result<(), PluginError> {
        let Some(res) = resources.first() else {
            return Err(PluginError::Invalid {
                plugin: self.id().into(),
                message: "lookup texture missing".into(),
            });
        };
        let lut = curve(params).bake(LUT_SIZE);
        match self.mode {
            Mode::Post | Mode::Pre => gpu.write_table(res, &lut),
            Mode::Preintegrated => {
                let table = preint::build(
                    &lut,
                    params.float("opacity") as f64,
                    gpu.slice_spacing as f64,
                );
                gpu.write_table(res, &table.texels_f32());
                if let Some(depth) = resources.get(1) {
                    gpu.write_table(depth, &table.depth_texels_f32());
                }
            }
        }
        Ok(())
    }
    /// Post: colour from the value alone; a value range can be visible when any table
    /// entry the GPU interpolates for it has α > 0 (the entries around both ends
    /// included). Pre: a sample interpolates classified voxels whose values lie in its
    /// brick's range (apron included), so the same test holds. Pre-integrated: the slab
    /// runs from the sample to where the ray meets the next slice, one step ahead
    /// ([`Transparency::ByValueAhead`]: the renderer widens the bricks' ranges by that
    /// step). Its table entry (i, j) integrates the baked table's cells between nodes i
    /// and j (opacity linear between nodes), and the filtered lookup of a slab whose
    /// ends lie in a range mixes entries whose nodes lie within the nodes around that
    /// range: the same test as post-classification's.
    fn transparency(&self, params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        let opacity = params.float("opacity");
        let visible = vwb_render::skipping::table_visibility(
            curve(params)
                .bake(LUT_SIZE)
                .iter()
                .map(|c| c[3] * opacity > 0.0)
                .collect(),
        );
        match self.mode {
            Mode::Preintegrated => Transparency::ByValueAhead(visible, 1.0),
            Mode::Post | Mode::Pre => Transparency::ByValue(visible),
        }
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        let lut = curve(params).bake(LUT_SIZE);
        let opacity = params.float("opacity") as f64;
        Some(match self.mode {
            Mode::Post => Box::new(Tf1dTwin { lut, opacity }),
            Mode::Pre => Box::new(PreTwin { lut, opacity }),
            Mode::Preintegrated => Box::new(PreintTwin {
                lut,
                opacity,
                centroid: params.enumeration("shade_at") == SHADE_AT[1],
                table: None,
            }),
        })
    }
}

/// CPU twin of `classify` (post-classification).
pub struct Tf1dTwin {
    pub lut: Vec<[f32; 4]>,
    pub opacity: f64,
}

impl CpuTwin for Tf1dTwin {
    fn classify(&self, _ctx: &CpuContext, s: &mut CpuSample) {
        let c = eval_lut(&self.lut, s.value.clamp(0.0, 1.0));
        s.color = DVec4::new(c[0], c[1], c[2], (c[3] * self.opacity).clamp(0.0, 1.0));
    }
}

/// CPU twin of pre-classification: the pre-pass (each voxel through the table,
/// opacity-weighted, rounded to the rgba16float target), interpolated trilinearly.
pub struct PreTwin {
    pub lut: Vec<[f32; 4]>,
    pub opacity: f64,
}

fn round_f16(v: f64) -> f64 {
    half::f16::from_f64(v).to_f64()
}

impl CpuTwin for PreTwin {
    fn classify(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let c = ctx.trilinear(s.tex, |i| {
            // the pre-pass computes in f32 and stores fp16
            let c = eval_lut(&self.lut, (ctx.scalars[i] as f64).clamp(0.0, 1.0));
            let a = c[3] as f32;
            let w = |v: f64| round_f16((v as f32 * a) as f64);
            DVec4::new(w(c[0]), w(c[1]), w(c[2]), round_f16(a as f64))
        });
        let rgb = if c.w > 0.0 {
            c.truncate() / c.w
        } else {
            DVec3::ZERO
        };
        s.color = rgb.extend((c.w * self.opacity).clamp(0.0, 1.0));
    }
}

/// CPU twin of pre-integrated classification: the same table (built for the frame's
/// spacing in `prepare`, rounded to f32 like the texture) and the same bilinear lookup
/// at (front, back).
pub struct PreintTwin {
    pub lut: Vec<[f32; 4]>,
    pub opacity: f64,
    /// `shade_at: centroid`: the sample's `shade_at` from the centroid table.
    pub centroid: bool,
    pub table: Option<preint::PreintTable>,
}

impl CpuTwin for PreintTwin {
    fn prepare(&mut self, ctx: &CpuContext) {
        let mut t = preint::build(&self.lut, self.opacity, ctx.spacing as f32 as f64);
        for e in &mut t.entries {
            *e = e.map(|v| v as f32 as f64);
        }
        for z in &mut t.depth {
            *z = *z as f32 as f64;
        }
        self.table = Some(t);
    }
    fn classify(&self, ctx: &CpuContext, s: &mut CpuSample) {
        let Some(table) = &self.table else {
            return;
        };
        let back_pos = s.pos + s.ray_dir * s.step;
        let (lo, hi) = ctx.volume_box();
        let back = ctx.value((back_pos - lo) / (hi - lo));
        s.color = table.lookup(s.value, back);
        if self.centroid {
            s.shade_at = table.lookup_depth(s.value, back);
        }
    }
}
