//! Parameters shared by the shading plugins (material, lights, gradient fade) and
//! their conversion for the CPU twins. The maths is in `vwb_render::shading` (CPU) and
//! at the end of `shaders/common.wgsl` (GPU).

use std::marker::PhantomData;
use std::sync::Arc;

use glam::{DVec3, DVec4};
use vwb_render::params::{Group, ParamSpec, ParamValues};
use vwb_render::plugin::{
    CpuContext, CpuSample, CpuTwin, Plugin, PrepassDecl, ShaderSource, Transparency, Volumes,
};
use vwb_render::shading::{GradientEstimator, Gradients, Light, LightKind, LightSpace, Material};

/// The four lights, a parameter group: light i's keys are `light{i}_on`, `_type`,
/// `_space`, `_vector` and `_color`, and `light{i}_on` switches it.
pub const LIGHTS: Group = Group::new("Light", 4).switch("light{}_on");

/// Default light vectors: a head light slightly up and right, then three fill lights.
const LIGHT_DEFAULTS: [[f32; 3]; 4] = [
    [0.3, 0.4, 1.0],
    [-1.0, 0.2, 0.3],
    [0.0, -1.0, 0.2],
    [0.0, 0.0, -1.0],
];

/// k_a, k_d, k_s and the shininess n (eqs 7.2–7.4; the thesis gives no defaults).
pub fn material_params(ka: f32, kd: f32, ks: f32, shininess: f32) -> Vec<ParamSpec> {
    vec![
        ParamSpec::float("ka", "Ambient k_a", 0.0, 1.0, ka).with_doc("eq 7.2"),
        ParamSpec::float("kd", "Diffuse k_d", 0.0, 1.0, kd).with_doc("eq 7.3"),
        ParamSpec::float("ks", "Specular k_s", 0.0, 1.0, ks).with_doc("eq 7.4"),
        ParamSpec::float_log("shininess", "Shininess n", 1.0, 256.0, shininess)
            .with_doc("exponent of the specular term (eq 7.4)"),
    ]
}

pub fn material(p: &ParamValues) -> Material {
    Material {
        ka: p.float("ka") as f64,
        kd: p.float("kd") as f64,
        ks: p.float("ks") as f64,
        shininess: p.float("shininess") as f64,
    }
}

/// The fade rule's floor (render/src/shading.rs).
pub fn fade_param() -> ParamSpec {
    ParamSpec::float_log("gradient_floor", "Gradient floor", 0.001, 1.0, 0.02)
        .with_doc("below this |∇f| (normalised value per voxel) shading fades linearly to unlit")
}

/// Parameters of the four lights (light 0 on by default, in view space).
pub fn light_params() -> Vec<ParamSpec> {
    LIGHTS.specs(|i| {
        let k = |member| LIGHTS.key(member, i);
        vec![
            ParamSpec::boolean(k("light{}_on"), "Light on", i == 0),
            ParamSpec::enumeration(
                k("light{}_type"),
                "Light type",
                &["directional", "point"],
                0,
            )
            .structural(),
            ParamSpec::enumeration(k("light{}_space"), "Light space", &["view", "world"], 0)
                .with_doc("view: x right, y up, z towards the viewer (points relative to the eye)"),
            ParamSpec::vec3(
                k("light{}_vector"),
                "Light direction / position",
                -10.0,
                10.0,
                LIGHT_DEFAULTS[i],
            )
            .with_doc("directional: towards the light; point: its position"),
            ParamSpec::color(k("light{}_color"), "Light colour", [1.0, 1.0, 1.0, 1.0]),
        ]
    })
}

/// The regions of a hook file around each light's `add_light` call
/// (`// light{i}: begin` … `// light{i}: end`).
const LIGHT_REGIONS: [&str; 4] = ["light0", "light1", "light2", "light3"];

/// The hook file with only the lights in `compiled` left in: the others' calls are
/// blanked ([`ShaderSource::without_regions`]). A branch on a light's `on` flag does not
/// save its cost on a CPU device, which runs the code of both sides of a branch when
/// its lanes may differ (measured on lavapipe: docs/perf.md, "Cheap shading"), so a
/// light that is off is compiled out; switching it on recomposes the pipeline.
///
/// A compiled light's kind is fixed in the code (`params.light{i}_type` becomes a
/// literal, so only its kind's branch of `light_dir` is left), and its vector is read in
/// world space from `light_world[i]` (`params.light{i}_space` becomes world), which an
/// appended `setup` hook fills once per ray with `light_world_vector`: the same
/// operations as per sample, so the image is the same, but out of the sample loop.
pub fn with_lights(
    file: &'static str,
    source: &'static str,
    compiled: [Option<LightKind>; 4],
) -> ShaderSource {
    let off: Vec<(&str, &str)> = LIGHT_REGIONS
        .iter()
        .zip(compiled)
        .filter(|(_, kind)| kind.is_none())
        .map(|(r, _)| (*r, ""))
        .collect();
    let mut shader = ShaderSource::without_regions(file, source, &off);
    if compiled.iter().all(Option::is_none) {
        return shader;
    }
    let src = shader.source.to_mut();
    let mut setup = String::from(
        "\n// appended by plugins/src/lighting.rs (`with_lights`): each light's vector in \
         world space, once per ray\nvar<private> light_world: array<vec3<f32>, 4>;\n\n\
         fn setup(r: Ray, uv: vec2<f32>) -> vec4<f32> {\n",
    );
    for (i, kind) in compiled.iter().enumerate() {
        let Some(kind) = kind else { continue };
        let k = match kind {
            LightKind::Directional => "0u",
            LightKind::Point => "1u",
        };
        *src = src
            .replace(&format!("params.light{i}_type"), k)
            .replace(&format!("params.light{i}_space"), "1u")
            .replace(
                &format!("params.light{i}_vector"),
                &format!("light_world[{i}]"),
            );
        setup.push_str(&format!(
            "    light_world[{i}] = light_world_vector({k}, params.light{i}_space, params.light{i}_vector);\n"
        ));
    }
    setup.push_str("    return vec4<f32>(0.0);\n}\n");
    src.push_str(&setup);
    shader
}

/// What each light slot compiles to: its kind where it is on, `None` where it is off.
pub fn compiled_lights(p: &ParamValues) -> [Option<LightKind>; 4] {
    let slots = light_slots(p);
    std::array::from_fn(|i| slots[i].map(|l| l.kind))
}

/// The lights that are on, for the CPU twin.
pub fn lights(p: &ParamValues) -> Vec<Light> {
    light_slots(p).into_iter().flatten().collect()
}

/// Each of the four light slots: its light, or None where it is off.
pub fn light_slots(p: &ParamValues) -> Vec<Option<Light>> {
    (0..LIGHTS.count)
        .map(|i| {
            p.boolean(LIGHTS.key("light{}_on", i))
                .then(|| light_of(p, i))
        })
        .collect()
}

fn light_of(p: &ParamValues, i: usize) -> Light {
    let k = |member| LIGHTS.key(member, i);
    Light {
        kind: if p.enumeration(k("light{}_type")) == "point" {
            LightKind::Point
        } else {
            LightKind::Directional
        },
        space: if p.enumeration(k("light{}_space")) == "world" {
            LightSpace::World
        } else {
            LightSpace::View
        },
        vector: DVec3::from(p.vec3(k("light{}_vector")).map(f64::from)),
        color: DVec3::from([0, 1, 2].map(|c| p.color(k("light{}_color"))[c] as f64)),
    }
}

/// A single view-space directional light (the head light of the isosurface and
/// environment-map plugins).
pub fn head_light_param() -> ParamSpec {
    ParamSpec::vec3(
        "light_vector",
        "Light direction (view)",
        -10.0,
        10.0,
        [0.3, 0.4, 1.0],
    )
    .with_doc("directional, in view space: x right, y up, z towards the viewer")
}

pub fn head_light(p: &ParamValues) -> Light {
    Light {
        kind: LightKind::Directional,
        space: LightSpace::View,
        vector: DVec3::from(p.vec3("light_vector").map(f64::from)),
        color: DVec3::ONE,
    }
}

/// A local-illumination model on the shared gradient estimators, fade rule and four
/// lights: what differs between such models is their id, their own parameters, their
/// hook file and the lit colour their twin computes; [`Lit`] is the plugin around it.
/// The hook file's `shade` reads `params.two_sided`, `params.gradient_floor` and the
/// lights `params.light{0..3}_*`, which [`Lit`] declares after the model's own.
pub trait LightingModel: Send + Sync + 'static {
    const ID: &'static str;
    const NAME: &'static str;
    const DESCRIPTION: &'static str;
    /// The hook file, as a path from the repository root, and its source.
    const FILE: &'static str;
    const SOURCE: &'static str;
    /// The CPU twin of the model's lighting.
    type Twin: LitColour;
    /// The model's own parameters.
    fn params() -> Vec<ParamSpec>;
    fn twin(params: &ParamValues) -> Self::Twin;
    /// The loop iterations its lighting runs per lit light
    /// ([`vwb_render::plugin::Plugin::loop_iterations`]); none by default.
    fn loop_iterations_per_light(_params: &ParamValues) -> u32 {
        0
    }
}

/// The lit colour of a model's CPU twin.
pub trait LitColour: Send + Sync + 'static {
    /// The lit colour of `base` at unit normal `n` (zero where there is no gradient)
    /// seen from `v` (unit, towards the viewer) at `pos`, under `lights`.
    fn lit(
        &self,
        ctx: &CpuContext,
        lights: &[Light],
        base: DVec3,
        n: DVec3,
        v: DVec3,
        pos: DVec3,
    ) -> DVec3;
}

/// The shading plugin of a [`LightingModel`]: the gradient estimator (structural), the
/// model's parameters, `two_sided`, `gradient_floor` and four lights; opacity is kept.
pub struct Lit<M> {
    pub gradient: GradientEstimator,
    /// The lights compiled in (those that are on, by kind: [`with_lights`]).
    pub lights: [Option<LightKind>; 4],
    model: PhantomData<fn() -> M>,
}

impl<M> Lit<M> {
    /// The model with light 0 on (the default parameters).
    pub fn new(gradient: GradientEstimator) -> Self {
        Self::with(gradient, [Some(LightKind::Directional), None, None, None])
    }
    pub fn with(gradient: GradientEstimator, lights: [Option<LightKind>; 4]) -> Self {
        Self {
            gradient,
            lights,
            model: PhantomData,
        }
    }
}

impl<M> Default for Lit<M> {
    fn default() -> Self {
        Self::new(GradientEstimator::default())
    }
}

impl<M: LightingModel> Plugin for Lit<M> {
    fn id(&self) -> &'static str {
        M::ID
    }
    /// Those of the model per light compiled in.
    fn loop_iterations(&self, params: &ParamValues) -> vwb_render::plugin::LoopIterations {
        let lights = self.lights.iter().flatten().count() as u32;
        vwb_render::plugin::LoopIterations {
            sample: lights * M::loop_iterations_per_light(params),
            scalar: 0,
        }
    }
    fn display_name(&self) -> &'static str {
        M::NAME
    }
    fn description(&self) -> &'static str {
        M::DESCRIPTION
    }
    fn params(&self) -> Vec<ParamSpec> {
        let mut p = vec![GradientEstimator::param()];
        p.extend(M::params());
        p.extend([
            ParamSpec::boolean("two_sided", "Two-sided", true)
                .with_doc("flip normals towards the viewer (else n = −∇f/|∇f|)"),
            fade_param(),
        ]);
        p.extend(light_params());
        p
    }
    fn shader(&self) -> ShaderSource {
        self.gradient
            .append_to(with_lights(M::FILE, M::SOURCE, self.lights))
    }
    fn prepass(&self) -> Option<PrepassDecl> {
        self.gradient.prepass()
    }
    fn configure(&self, params: &ParamValues) -> Option<Arc<dyn Plugin>> {
        let gradient = GradientEstimator::from_params(params);
        let on = compiled_lights(params);
        (gradient != self.gradient || on != self.lights)
            .then(|| Arc::new(Self::with(gradient, on)) as Arc<dyn Plugin>)
    }
    /// Shading changes colours only.
    fn transparency(&self, _params: &ParamValues, _volumes: &Volumes<'_>) -> Transparency {
        Transparency::Keeps
    }
    fn cpu_twin(&self, params: &ParamValues) -> Option<Box<dyn CpuTwin>> {
        Some(Box::new(LitTwin {
            gradients: Gradients::new(self.gradient),
            model: M::twin(params),
            lights: lights(params),
            two_sided: params.boolean("two_sided"),
            floor: params.float("gradient_floor") as f64,
        }))
    }
}

/// CPU twin of a [`Lit`] plugin: the shading normal and fade weight, then the model.
pub struct LitTwin<T> {
    pub gradients: Gradients,
    pub model: T,
    pub lights: Vec<Light>,
    pub two_sided: bool,
    pub floor: f64,
}

impl<T: LitColour> CpuTwin for LitTwin<T> {
    fn prepare(&mut self, ctx: &CpuContext) {
        self.gradients.prepare(ctx);
    }
    fn shade(&self, ctx: &CpuContext, s: &mut CpuSample) {
        if s.color.w <= 0.0 {
            return;
        }
        let v = -s.ray_dir;
        let (_, n, w) =
            self.gradients
                .normal(ctx, s.shading_tex(ctx), self.floor, v, self.two_sided);
        let base = s.color.truncate();
        let lit = self.model.lit(ctx, &self.lights, base, n, v, s.pos);
        s.color = DVec4::from((base.lerp(lit, w), s.color.w));
        s.normal = n;
    }
}

/// Fixtures for the shading plugins' CPU tests.
#[cfg(test)]
pub mod testing {
    use glam::{DVec3, DVec4};
    use vwb_render::params::{ParamValue, ParamValues};
    use vwb_render::plugin::{CpuContext, CpuSample, Plugin};
    use vwb_render::volume::{Volume, VoxelData};

    /// f = x/(n − 1): ∇f points along +x, so the outward normal is −x.
    pub fn ramp_x(n: u32) -> Volume {
        let data = (0..n * n * n).map(|i| (i % n) as f32).collect();
        Volume::new("ramp", [n; 3], 1, [1.0; 3], VoxelData::F32(data)).unwrap()
    }

    /// A constant volume (no gradient).
    pub fn constant(n: u32) -> Volume {
        Volume::new(
            "c",
            [n; 3],
            1,
            [1.0; 3],
            VoxelData::F32(vec![3.0; (n * n * n) as usize]),
        )
        .unwrap()
    }

    /// The base colour the fixtures shade.
    pub const BASE: DVec4 = DVec4::new(0.8, 0.4, 0.2, 0.5);

    /// The plugin's twin (as configured by `params`) shading [`BASE`] at the centre of
    /// `vol`, seen along `ray_dir`.
    pub fn shaded(
        plugin: &dyn Plugin,
        vol: &Volume,
        params: &ParamValues,
        ray_dir: DVec3,
    ) -> DVec4 {
        let scalars = vol.normalized_scalars();
        let ctx = CpuContext::new(vol, &scalars);
        let mut twin = plugin.configure(params).map_or_else(
            || plugin.cpu_twin(params).unwrap(),
            |p| p.cpu_twin(params).unwrap(),
        );
        twin.prepare(&ctx);
        let mut s = CpuSample {
            tex: DVec3::splat(0.5),
            ray_dir,
            color: BASE,
            ..Default::default()
        };
        twin.shade(&ctx, &mut s);
        s.color
    }

    /// The plugin's defaults with light 0 as a world-space directional light along
    /// `towards_light` and a fade floor low enough for [`ramp_x`]'s gradient.
    pub fn world_light(plugin: &dyn Plugin, towards_light: [f32; 3]) -> ParamValues {
        let mut p = ParamValues::defaults(&plugin.params());
        p.set("light0_space", ParamValue::Enum("world".into()));
        p.set("light0_vector", ParamValue::Vec3(towards_light));
        p.set("gradient_floor", ParamValue::Float(0.001));
        p
    }
}
