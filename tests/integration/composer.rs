//! Composer: golden output, per-instance naming, error mapping to file:line, the last
//! good pipeline surviving a broken plugin, change tracking, device limits.

use vwb_render::Renderer;
use vwb_render::composer::{ComposeError, TargetFormat, compose};
use vwb_render::params::{ParamSpec, ParamValue};
use vwb_render::plugin::{Plugin, PluginInstance, ShaderSource};
use vwb_render::renderer::{Backend, RenderError, StackChange};

use crate::common::*;

struct Fixture {
    id: &'static str,
    shader: ShaderSource,
}

impl Plugin for Fixture {
    fn id(&self) -> &'static str {
        self.id
    }
    fn display_name(&self) -> &'static str {
        "fixture"
    }
    fn params(&self) -> Vec<ParamSpec> {
        vec![ParamSpec::float("gain", "Gain", 0.0, 2.0, 1.0)]
    }
    fn shader(&self) -> ShaderSource {
        self.shader.clone()
    }
}

fn broken() -> PluginInstance {
    PluginInstance::new(std::sync::Arc::new(Fixture {
        id: "shade.broken_fixture",
        shader: ShaderSource::new_static(
            "tests/fixtures/broken_plugin.wgsl",
            include_str!("../fixtures/broken_plugin.wgsl"),
        ),
    }))
}

#[test]
fn golden_composition() {
    let reg = registry();
    let tf = reg.get("classify.tf1d").unwrap();
    let smooth = reg.get("test.smooth").unwrap();
    let shadow = reg.get("test.slice_shadow").unwrap();
    // two instances of one plugin, plus a pre-pass and a per-slice state
    let stack: Vec<&dyn Plugin> = vec![smooth.as_ref(), tf.as_ref(), shadow.as_ref(), tf.as_ref()];
    let c = compose(&stack, TargetFormat::Rgba16Float, &wgpu::Limits::default()).unwrap();
    assert!(
        c.main.source.contains("fn p1_tf1d_classify(")
            && c.main.source.contains("fn p3_tf1d_classify(")
    );
    assert!(
        c.main
            .source
            .contains("    s = p1_tf1d_classify(s);\n    s = p3_tf1d_classify(s);")
    );
    assert!(c.main.source.contains("fn cs_update_2("));
    // bindings are numbered once, in stack order
    let g1: Vec<(u32, String)> = c
        .bindings
        .iter()
        .filter(|b| b.group == 1)
        .map(|b| (b.binding, b.local_name.clone()))
        .collect();
    assert_eq!(
        g1,
        vec![
            (0, "params".into()),
            (1, "smoothed".into()),
            (2, "params".into()),
            (3, "lut".into()),
            (4, "params".into()),
            (5, "params".into()),
            (6, "lut".into())
        ]
    );
    write_or_compare_text(
        &repo().join("tests/golden/composed_main.wgsl"),
        &c.main.source,
    );
    let pre = &c.instances[0].prepass.as_ref().unwrap().0;
    write_or_compare_text(
        &repo().join("tests/golden/composed_prepass_smooth.wgsl"),
        &pre.source,
    );
}

#[test]
fn every_origin_line_is_mapped() {
    let reg = registry();
    let tf = reg.get("classify.tf1d").unwrap();
    let c = compose(
        &[tf.as_ref()],
        TargetFormat::Rgba32Float,
        &wgpu::Limits::default(),
    )
    .unwrap();
    assert_eq!(c.main.source.lines().count(), c.main.origins.len());
    // the classify hook comes from the plugin's own file and line
    let line = c
        .main
        .source
        .lines()
        .position(|l| l.starts_with("fn p0_tf1d_classify("))
        .unwrap() as u32
        + 1;
    let origin = c.main.origin(line).unwrap().to_string();
    assert!(
        origin.starts_with("plugins/src/classify_tf1d/tf1d.wgsl:"),
        "{origin}"
    );
}

#[test]
fn broken_plugin_is_reported_at_file_line_and_old_pipeline_keeps_rendering() {
    let gpu = gpu();
    let mut r = Renderer::new(gpu, demo()).unwrap();
    let s = settings(64, 64, Backend::Raster);
    let good = vec![instance("classify.tf1d")];
    let before = render(&mut r, &good, TargetFormat::Rgba16Float, &s);
    assert!(
        mean_luma(&rgb(&before)) > 0.01,
        "the good pipeline shows something"
    );

    let mut bad = good.clone();
    bad.push(broken());
    let err = r.update_stack(&bad, TargetFormat::Rgba16Float).unwrap_err();
    match &err {
        RenderError::Compose(ComposeError::Shader {
            file, line, plugin, ..
        }) => {
            assert_eq!(file, "tests/fixtures/broken_plugin.wgsl");
            assert_eq!(*line, 7);
            assert_eq!(plugin.as_deref(), Some("shade.broken_fixture"));
        }
        other => panic!("unexpected error {other}"),
    }
    let msg = err.to_string();
    assert!(
        msg.starts_with("tests/fixtures/broken_plugin.wgsl:7:"),
        "{msg}"
    );
    assert!(msg.contains("undeclared_gain"), "{msg}");

    // the previous pipeline is still in use
    assert_eq!(r.active_plugins(), vec!["classify.tf1d"]);
    r.render(&s).unwrap();
    let after = r.read_pixels().unwrap().2;
    assert_eq!(
        before, after,
        "the last good pipeline renders the same image"
    );
}

/// Plugin code that assigns to its parameters (or the frame), private copies of
/// uniforms, is refused at its own file and line.
#[test]
fn a_plugin_that_writes_its_parameters_is_refused_at_its_line() {
    let writer = PluginInstance::new(std::sync::Arc::new(Fixture {
        id: "shade.params_writer_fixture",
        shader: ShaderSource::new_static(
            "tests/fixtures/params_writer.wgsl",
            include_str!("../fixtures/params_writer.wgsl"),
        ),
    }));
    let err = compose(
        &[writer.plugin.as_ref()],
        TargetFormat::Rgba16Float,
        &wgpu::Limits::default(),
    )
    .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.starts_with("tests/fixtures/params_writer.wgsl:6:"),
        "{msg}"
    );
    assert!(msg.contains("assigns to `params`"), "{msg}");
}

#[test]
fn wrong_hook_signature_names_the_function_line() {
    let p = Fixture {
        id: "classify.bad_signature",
        shader: ShaderSource::new_static(
            "fixtures/bad_signature.wgsl",
            "// a classify hook that returns the wrong type\n\nfn classify(s: Sample) -> f32 {\n    return s.value;\n}\n",
        ),
    };
    let err = compose(&[&p], TargetFormat::Rgba16Float, &wgpu::Limits::default()).unwrap_err();
    let msg = err.to_string();
    assert!(msg.starts_with("fixtures/bad_signature.wgsl:3:"), "{msg}");
    assert!(
        msg.contains("must be fn classify(Sample) -> Sample"),
        "{msg}"
    );
}

/// Each instance with a `setup` hook gets a record of its own: two instances of
/// `sample.jitter` compose (naga-validated) with two prefixed `ray_record`s, each set in
/// `run_setup` and read by its own instance's `sample` hook; a `setup` with the wrong
/// signature is refused at its line, and a file that reads `ray_record` without
/// defining `setup` is refused naming the identifier.
#[test]
fn each_setup_instance_has_its_own_ray_record() {
    let jitter = vwb_plugins::registry().get("sample.jitter").unwrap();
    let c = compose(
        &[jitter.as_ref(), jitter.as_ref()],
        TargetFormat::Rgba16Float,
        &wgpu::Limits::default(),
    )
    .unwrap();
    let src = &c.main.source;
    let records: Vec<&str> = src
        .lines()
        .filter(|l| l.starts_with("var<private>") && l.contains("ray_record"))
        .collect();
    assert_eq!(records.len(), 2, "{records:?}");
    let names: Vec<String> = records
        .iter()
        .map(|l| {
            l.split_whitespace()
                .nth(1)
                .unwrap()
                .trim_end_matches(':')
                .to_string()
        })
        .collect();
    assert_ne!(names[0], names[1]);
    for n in &names {
        assert!(
            src.contains(&format!("    {n} = ")),
            "{n} is set in run_setup"
        );
        assert!(
            src.contains(&format!("let d = {n}.x * s.step;")),
            "{n} is read"
        );
    }

    let bad = Fixture {
        id: "sample.bad_setup",
        shader: ShaderSource::new_static(
            "fixtures/bad_setup.wgsl",
            "// setup must take the ray

fn setup(uv: vec2<f32>) -> vec4<f32> {
    return vec4<f32>(uv, 0.0, 0.0);
}
",
        ),
    };
    let msg = compose(&[&bad], TargetFormat::Rgba16Float, &wgpu::Limits::default())
        .unwrap_err()
        .to_string();
    assert!(msg.starts_with("fixtures/bad_setup.wgsl:3:"), "{msg}");
    assert!(
        msg.contains("must be fn setup(Ray, vec2<f32>) -> vec4<f32>"),
        "{msg}"
    );

    let no_setup = Fixture {
        id: "sample.no_setup",
        shader: ShaderSource::new_static(
            "fixtures/no_setup.wgsl",
            "fn sample(s_in: Sample) -> Sample {
    var s = s_in;
    s.value = ray_record.x;
    return s;
}
",
        ),
    };
    let msg = compose(
        &[&no_setup],
        TargetFormat::Rgba16Float,
        &wgpu::Limits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(msg.starts_with("fixtures/no_setup.wgsl:3:"), "{msg}");
    assert!(msg.contains("ray_record"), "{msg}");
}

/// A plugin may supply the scalar its sample hook gives (`scalar`, `scalar_grid`):
/// the stack's gradient estimators then differentiate it (`shading_value`). Its
/// signature is checked like a hook's, `scalar_grid` alone is refused, and
/// `shading_value` is a shared name.
#[test]
fn a_supplied_scalar_is_what_the_gradients_differentiate() {
    let fixture = |id: &'static str, file: &'static str, src: &'static str| Fixture {
        id,
        shader: ShaderSource::new_static(file, src),
    };
    let limits = wgpu::Limits::default();
    let p = fixture(
        "sample.doubled",
        "fixtures/doubled.wgsl",
        "fn sample(s: Sample) -> Sample {\n    var o = s;\n    o.value = 2.0 * s.value;\n    return o;\n}\n\nfn scalar(tex: vec3<f32>) -> f32 {\n    return 2.0 * volume_value(tex);\n}\n",
    );
    let c = compose(&[&p], TargetFormat::Rgba16Float, &limits).unwrap();
    assert!(
        c.main.source.contains(
            "fn shading_value(tex: vec3<f32>) -> f32 {\n    return p0_doubled_scalar(tex);"
        ),
        "the provider's scalar"
    );
    // without scalar_grid, the volume's grid
    assert!(
        c.main
            .source
            .contains("fn shading_grid() -> vec3<f32> {\n    return frame.volume_dims.xyz;")
    );
    let plain = compose(
        &[&*instance("classify.tf1d").plugin],
        TargetFormat::Rgba16Float,
        &limits,
    )
    .unwrap();
    assert!(
        plain
            .main
            .source
            .contains("fn shading_value(tex: vec3<f32>) -> f32 {\n    return volume_value(tex);")
    );
    let bad = fixture(
        "sample.bad_scalar",
        "fixtures/bad_scalar.wgsl",
        "fn sample(s: Sample) -> Sample { return s; }\n\nfn scalar(tex: vec3<f32>) -> vec4<f32> {\n    return vec4<f32>(0.0);\n}\n",
    );
    let msg = compose(&[&bad], TargetFormat::Rgba16Float, &limits)
        .unwrap_err()
        .to_string();
    assert!(msg.starts_with("fixtures/bad_scalar.wgsl:3:"), "{msg}");
    assert!(msg.contains("must be fn scalar(vec3<f32>) -> f32"), "{msg}");
    let grid_only = fixture(
        "sample.grid_only",
        "fixtures/grid_only.wgsl",
        "fn sample(s: Sample) -> Sample { return s; }\nfn scalar_grid() -> vec3<f32> { return vec3<f32>(1.0); }\n",
    );
    let msg = compose(&[&grid_only], TargetFormat::Rgba16Float, &limits)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("scalar_grid but no scalar"), "{msg}");
    let clash = fixture(
        "shade.clash3",
        "fixtures/clash3.wgsl",
        "fn shade(s: Sample) -> Sample { return s; }\n\nfn shading_value(t: vec3<f32>) -> f32 { return 0.0; }\n",
    );
    let msg = compose(&[&clash], TargetFormat::Rgba16Float, &limits)
        .unwrap_err()
        .to_string();
    assert!(
        msg.starts_with("fixtures/clash3.wgsl:3:") && msg.contains("shading_value"),
        "{msg}"
    );
}

/// The parameters that a stack's code reads travel to the raster fragments as flat
/// words of the slice vertices (composer.rs `routed_params`), as many as the device's
/// inter-stage locations hold, and no others.
#[test]
fn the_fragments_take_the_parameters_they_read_from_the_vertices() {
    let reg = registry();
    let tf = reg.get("classify.tf1d").unwrap();
    let bp = reg.get("shade.blinn_phong").unwrap();
    let stack: Vec<&dyn Plugin> = vec![tf.as_ref(), bp.as_ref()];
    let routed = |locations: u32| {
        let limits = wgpu::Limits {
            max_inter_stage_shader_variables: locations,
            ..Default::default()
        };
        let src = compose(&stack, TargetFormat::Rgba16Float, &limits)
            .unwrap()
            .main
            .source;
        let body = src
            .split("fn params_from_vertex(in: VsOut) {\n")
            .nth(1)
            .and_then(|b| b.split('}').next())
            .unwrap_or_default()
            .to_string();
        let fields = (0..64)
            .filter(|l| src.contains(&format!("@location({l}) @interpolate(flat) params_")))
            .collect::<Vec<u32>>();
        (body, fields)
    };
    // none free: nothing routed, and the module is valid without it
    let (body, fields) = routed(14);
    assert!(body.trim().is_empty() && fields.is_empty(), "{body}");
    // lavapipe's 31 locations: every member the shading reads
    let (body, fields) = routed(31);
    for key in [
        "shininess",
        "kd",
        "ks",
        "ka",
        "gm_scale",
        "gm_opacity",
        "light0_on",
        "light0_color",
        "light0_vector",
    ] {
        assert!(
            body.contains(&format!("p1_blinn_phong_params.{key} = ")),
            "{key} is read, so routed:\n{body}"
        );
    }
    assert!(body.contains("p1_blinn_phong_params.light0_color = vec4<f32>(bitcast<f32>(in."));
    // the lights that are off are compiled out, so not read, so not routed
    assert!(!body.contains("light1_"), "{body}");
    assert!(!fields.is_empty() && fields.iter().all(|&l| (14..31).contains(&l)));
    // the default limit: the two free locations hold what fits
    let (short, fields16) = routed(16);
    assert_eq!(fields16, vec![14, 15]);
    let all: Vec<&str> = body
        .lines()
        .map(|l| l.split(" = ").next().unwrap())
        .collect();
    let some: Vec<&str> = short
        .lines()
        .map(|l| l.split(" = ").next().unwrap())
        .collect();
    assert!(!some.is_empty() && some.len() < all.len(), "{short}");
    assert!(some.iter().all(|m| all.contains(m)), "{short}");
}

#[test]
fn clash_with_shared_names_is_reported() {
    let p = Fixture {
        id: "shade.clash",
        shader: ShaderSource::new_static(
            "fixtures/clash.wgsl",
            "fn shade(s: Sample) -> Sample { return s; }\nfn under(a: f32) -> f32 { return a; }\n",
        ),
    };
    // `under` is a template function, not in common.wgsl: the per-instance prefix
    // keeps the plugin's own `under` apart, so this composes.
    compose(&[&p], TargetFormat::Rgba16Float, &wgpu::Limits::default()).unwrap();
    let q = Fixture {
        id: "shade.clash2",
        shader: ShaderSource::new_static(
            "fixtures/clash2.wgsl",
            "fn shade(s: Sample) -> Sample { return s; }\n\nfn volume_value(t: vec3<f32>) -> f32 { return 0.0; }\n",
        ),
    };
    let err = compose(&[&q], TargetFormat::Rgba16Float, &wgpu::Limits::default()).unwrap_err();
    assert!(err.to_string().contains("fixtures/clash2.wgsl:"), "{err}");
}

#[test]
fn disabled_plugins_contribute_no_code_and_changes_are_tracked() {
    let gpu = gpu();
    let mut r = Renderer::new(gpu, demo()).unwrap();
    let mut stack = vec![instance("classify.tf1d"), instance("test.smooth")];
    stack[1].enabled = false;
    assert_eq!(
        r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap(),
        StackChange::Recomposed
    );
    let wgsl = r.composed_wgsl().unwrap().to_string();
    assert!(
        !wgsl.contains("smooth"),
        "a disabled plugin contributes no code"
    );
    assert_eq!(
        r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap(),
        StackChange::None
    );
    stack[0].params.set("opacity", ParamValue::Float(0.5));
    assert_eq!(
        r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap(),
        StackChange::Params,
        "a parameter change only rewrites uniforms"
    );
    assert_eq!(r.composed_wgsl().unwrap(), wgsl);
    stack[1].enabled = true;
    assert_eq!(
        r.update_stack(&stack, TargetFormat::Rgba16Float).unwrap(),
        StackChange::Recomposed
    );
    assert!(r.composed_wgsl().unwrap().contains("p1_smooth_sample"));
    assert_eq!(
        r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap(),
        StackChange::Recomposed,
        "the target format is structural"
    );
}

#[test]
fn device_limits_are_checked() {
    let reg = registry();
    let tf = reg.get("classify.tf1d").unwrap();
    let limits = wgpu::Limits {
        max_sampled_textures_per_shader_stage: 2,
        ..wgpu::Limits::default()
    };
    let stack: Vec<&dyn Plugin> = vec![tf.as_ref(), tf.as_ref()];
    let err = compose(&stack, TargetFormat::Rgba16Float, &limits).unwrap_err();
    assert!(matches!(err, ComposeError::Limits { .. }), "{err}");
    assert!(err.to_string().contains("sampled textures"), "{err}");
}

#[test]
fn duplicate_ids_are_rejected_by_the_builtin_registry() {
    let mut reg = registry();
    let again = reg.get("classify.tf1d").unwrap();
    assert!(reg.register(again).is_err());
}
