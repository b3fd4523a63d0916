// shade.envmap: diffuse and specular reflection maps (Rezk-Salama 2001 §7.4) in the
// longitude–latitude parameterisation, blended with a Blinn–Phong head light. The
// diffuse map (`irradiance`) is indexed by the normal, the reflective map
// (`radiance`) by the reflection vector. Lookups are bilinear with u wrapping, done
// with textureLoad so that the CPU twin (envmap.rs) matches exactly. `gradient_at` is
// appended by the estimator.

const PI: f32 = 3.14159265358979;

// Longitude–latitude coordinate of a world direction (+y up; u = 0.5 looks down −z).
fn latlong_uv(d: vec3<f32>) -> vec2<f32> {
    let u = 0.5 + (atan2(d.x, -d.z) + radians(params.rotation_deg)) / (2.0 * PI);
    let v = acos(clamp(d.y, -1.0, 1.0)) / PI;
    return vec2<f32>(u - floor(u), v);
}

fn latlong(t: texture_2d<f32>, d: vec3<f32>) -> vec3<f32> {
    let size = vec2<i32>(textureDimensions(t));
    let uv = latlong_uv(d);
    let x = uv.x * f32(size.x) - 0.5;
    let y = clamp(uv.y * f32(size.y) - 0.5, 0.0, f32(size.y - 1));
    let xf = floor(x);
    let yf = floor(y);
    let fx = x - xf;
    let fy = y - yf;
    let x0 = ((i32(xf) % size.x) + size.x) % size.x;
    let x1 = (x0 + 1) % size.x;
    let y0 = i32(yf);
    let y1 = min(y0 + 1, size.y - 1);
    let top = mix(textureLoad(t, vec2<i32>(x0, y0), 0).rgb, textureLoad(t, vec2<i32>(x1, y0), 0).rgb, fx);
    let bottom = mix(textureLoad(t, vec2<i32>(x0, y1), 0).rgb, textureLoad(t, vec2<i32>(x1, y1), 0).rgb, fx);
    return mix(top, bottom, fy);
}

fn shade(s: Sample) -> Sample {
    var o = s;
    // a transparent sample contributes nothing whatever its colour: skip the lighting
    if (s.color.a <= 0.0) {
        return o;
    }
    let v = -s.ray_dir;
    let nw = shading_normal(gradient_at(shading_tex(s)), params.gradient_floor, v, true);
    if (nw.w <= 0.0) {
        return o;
    }
    let n = nw.xyz;
    let base = s.color.rgb;
    let env = base * (params.ka + params.kd_env * latlong(irradiance, n)) + params.ks_env * latlong(radiance, reflect(-v, n));
    let f = blinn_phong_factors(n, v, light_dir(0u, 1u, head_light, s.pos), params.shininess);
    let bp = base * (params.ka + params.kd * f.x) + vec3<f32>(params.ks * f.y);
    o.color = vec4<f32>(mix(base, mix(env, bp, params.phong_weight), nw.w), s.color.a);
    o.normal = n;
    return o;
}

// The head light's world-space direction, once per ray: `light_world_vector` reads only
// uniforms, and a CPU device would evaluate it at every sample (docs/perf.md, "Light
// vectors once per ray"); `light_dir` then reads it as a world-space vector.
var<private> head_light: vec3<f32>;

fn setup(r: Ray, uv: vec2<f32>) -> vec4<f32> {
    head_light = light_world_vector(0u, 0u, params.light_vector);
    return vec4<f32>(0.0);
}
