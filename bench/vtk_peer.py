#!/usr/bin/env python3
"""VTK peer benchmark: vwb and VTK render the same scene, timed in one run.

For each preset, `vwb scene` describes what vwb renders (volume, world box, camera,
256-entry transfer-function table, slice spacing, background) as JSON. This script
rebuilds that scene in VTK (vtkGPUVolumeRayCastMapper by default: linear
interpolation, no shading, sample distance = slice spacing, opacity per smallest voxel
side), times VTK's Render() and `vwb render --timings` for both vwb backends, saves
the images (each alone and vwb | VTK side by side) and prints their RMS difference in
8-bit RGB (a sanity check that the camera and transfer-function mapping agree, not a
pass/fail).

Coordinates: vwb's world box is centred on the origin, longest side 1, and covers whole
voxels (texel centres at (i + 0.5)/n); vtkImageData with origin 0 puts voxel i at
i·spacing. So  vtk = (p − box_min)/(box_max − box_min) · dims · spacing − spacing/2,
a uniform scale plus a translation (directions such as the view-up are unchanged).

By default vwb runs on lavapipe and VTK on Mesa llvmpipe (EGL, no X server), both with
LP_NUM_THREADS=2 unless set. Needs `pip install vtk pynrrd numpy pillow` (not part of
the test set-up). Usage:

    python3 bench/vtk_peer.py                        # demo + CT head, 512², CPU drivers
    python3 bench/vtk_peer.py --preset presets/demo.ron --frames 5 -o /tmp/peer
    python3 bench/vtk_peer.py --mapper fixed --rounds 5  # ratios robust to a drifting host load
    python3 bench/vtk_peer.py --scene-json demo.json # scene from a file, not `vwb scene`
    python3 bench/vtk_peer.py --mapper smart         # vtkSmartVolumeMapper (or: fixed)
    python3 bench/vtk_peer.py --gl x                 # GLX (re-runs under xvfb-run -a)
    python3 bench/vtk_peer.py --write-docs           # rewrite the vtk-peer block in docs/perf.md
    python3 bench/vtk_peer.py --self-error           # also the speed ratio at equal self-error
    python3 bench/vtk_peer.py --preset presets/ct_dos.ron --shadows 0.3,1.0
                                                     # VTK's volumetric shadows against vwb's DOS

Self-convergence error (--self-error): each renderer's image at its default step
against its own image at 1/8 of that step (RMS, 8-bit RGB), VTK's and every vwb
variant's (vwb's fine image with an rgba32float eye buffer). A renderer that is fast because it samples coarsely shows it here. For each
vwb variant whose self-error exceeds VTK's, the script refines vwb's slice spacing
(÷1.1, ÷1.2, ÷1.3, ÷1.4, ÷1.5, ÷1.75, ÷2, ÷3, ÷4) until its self-error is at most VTK's, times it there, and quotes
the speed ratio at that spacing: the ratio at equal (or lower) self-error.
"""

import argparse
import json
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nrrd  # PyPI: pynrrd
import numpy as np
import vtk  # reads VTK_DEFAULT_OPENGL_WINDOW when a window is made, not at import
from PIL import Image
from vtk.util import numpy_support

from doclib import LAVAPIPE_ICD, REPO, default_vwb, machine_line, write_block

JITTER_DEG = 1e-3  # camera azimuth jitter between timed VTK frames, undone on the next
WARMUP = 2  # untimed frames before the timed ones (as `vwb render --timings`)


def stats(ms):
    """(median, min, max) of a list of milliseconds."""
    return statistics.median(ms), min(ms), max(ms)


def pooled(turns):
    """Several rounds' (median, min, max) as one: the median of the medians, the least
    min, the largest max."""
    return (statistics.median(t[0] for t in turns), min(t[1] for t in turns),
            max(t[2] for t in turns))


def relative(err, level):
    """A self-error over its image's mean 8-bit level."""
    return err / max(level, 1e-9)


def fmt(t):
    """A (median, min, max) triple as 'median (min–max)'."""
    return f"{t[0]:.1f} ({t[1]:.1f}–{t[2]:.1f})" if t else "n/a"


# ---------------------------------------------------------------------------- vwb


def vwb_scene(vwb, preset, size, spacing, env):
    cmd = [vwb, "scene", "--preset", preset, "--size", size]
    if spacing is not None:
        cmd += ["--spacing", str(spacing)]
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{shlex.join(cmd)} failed (a vwb without `scene`? rebuild it, or pass "
                 f"--scene-json FILE):\n{p.stderr}")
    return json.loads(p.stdout)


# vwb variants timed against VTK: (label, backend, extra arguments). VTK's ray caster
# terminates rays early, so the last row is the like-for-like one.
VWB_VARIANTS = [
    ("raster", "raster", []),
    ("compute", "compute", []),
    ("compute + early termination 0.99", "compute", ["--early-termination", "0.99"]),
]


def vwb_render(vwb, scene, backend, frames, png, env, extra=()):
    """Runs `vwb render --timings` on the scene's preset, size and slice spacing."""
    img = scene["image"]
    cmd = [vwb, "render", "--preset", scene["preset"],
           "--size", f"{img['width']}x{img['height']}",
           "--spacing", str(scene["slice_spacing_voxels"]), "--backend", backend,
           "--timings", "--frames", str(frames), "-o", str(png), *extra]
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{shlex.join(cmd)} failed:\n{p.stderr}")
    text = p.stdout + p.stderr

    def grab(key):
        m = re.search(rf"^{key} median ([\d.]+) min ([\d.]+) max ([\d.]+)", text, re.M)
        return tuple(float(x) for x in m.groups()) if m else None

    slices = re.search(r"(\d+) slices", text)
    adapter = re.search(r"^adapter: (.*)$", text, re.M)
    return {
        "wall": grab("wall_ms"),
        "gpu": grab("gpu_ms"),
        "slices": int(slices.group(1)) if slices else None,
        "adapter": adapter.group(1).strip() if adapter else "?",
    }


def with_spacing(scene, spacing):
    """A copy of the scene sampled every `spacing` voxels (vwb slices and VTK steps)."""
    return {**scene, "slice_spacing_voxels": spacing}


# Refinements of vwb's slice spacing tried, in order, to reach VTK's self-error.
REFINE = (1.1, 1.2, 1.3, 1.4, 1.5, 1.75, 2.0, 3.0, 4.0)
REFERENCE_DIVISOR = 8  # self-error reference: 1/8 of the default step


def rms(a, b):
    """RMS difference of two (h, w, 3) uint8 images in 8-bit units (None if sizes differ)."""
    if a.shape != b.shape:
        return None
    return float(np.sqrt(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)))


def read_png(path):
    return np.asarray(Image.open(path).convert("RGB"))


# ---------------------------------------------------------------------------- VTK


def load_scalars(scene):
    """The volume as a C-ordered (z, y, x) array; vector volumes become magnitudes."""
    vol = scene["volume"]
    path = vol["path"] or vol["demo_path"]
    data, _ = nrrd.read(str(REPO / path), index_order="C")
    nx, ny, nz = vol["dims"]
    if vol["components"] > 1:
        # A leading component axis in the file is the last one in C order.
        data = np.linalg.norm(data.astype(np.float32), axis=-1)
    if data.shape != (nz, ny, nx):
        sys.exit(f"{path}: shape {data.shape[::-1]} (x, y, z) is not the scene's dims {vol['dims']}")
    return np.ascontiguousarray(data)


class WorldToVtk:
    """vwb world coordinates → VTK physical coordinates (uniform scale + translation)."""

    def __init__(self, vol):
        self.box_min = np.array(vol["box_min"], float)
        extent = np.array(vol["box_max"], float) - self.box_min
        self.spacing = np.array(vol["spacing"], float)
        physical = np.array(vol["dims"], float) * self.spacing
        scales = physical / extent
        if np.ptp(scales) > 1e-4 * scales.mean():
            sys.exit(f"scene box {extent} is not a uniform scale of the volume {physical}")
        self.scale = float(scales.mean())

    def point(self, p):
        return (np.array(p, float) - self.box_min) * self.scale - 0.5 * self.spacing


def build_vtk(scene, mapper_kind, shadows=None):
    """A render window holding the scene; returns (window, camera, mapper). `shadows`:
    (reach, blend) of the GPU mapper's volumetric shadows (shading on)."""
    vol, cam, img = scene["volume"], scene["camera"], scene["image"]
    scalars = load_scalars(scene)
    image = vtk.vtkImageData()
    image.SetDimensions(*vol["dims"])
    image.SetSpacing(*vol["spacing"])
    image.SetOrigin(0.0, 0.0, 0.0)
    arr = numpy_support.numpy_to_vtk(scalars.ravel(), deep=True)
    arr.SetName("scalars")
    image.GetPointData().SetScalars(arr)

    prop = vtk.vtkVolumeProperty()
    prop.SetInterpolationTypeToLinear()
    shading = scene.get("shading")
    if shading:  # vwb's shade.blinn_phong: VTK's Phong shading with its head light
        prop.ShadeOn()
        prop.SetAmbient(shading["ka"])
        prop.SetDiffuse(shading["kd"])
        prop.SetSpecular(shading["ks"])
        prop.SetSpecularPower(shading["shininess"])
    elif shadows:  # VTK's volumetric scattering shades; its default material
        prop.ShadeOn()
    else:
        prop.ShadeOff()
    unit = float(min(vol["spacing"]))  # vwb opacities are per smallest voxel side
    prop.SetScalarOpacityUnitDistance(unit)
    # Without classify.tf1d vwb classifies with the grey ramp (v, v, v, v).
    lut = scene["tf"]["lut"] if scene["tf"] else [[v] * 4 for v in np.linspace(0.0, 1.0, 256)]
    lo, hi = vol["range"]
    hi = hi if hi > lo else lo + 1.0
    color, opacity = vtk.vtkColorTransferFunction(), vtk.vtkPiecewiseFunction()
    for i, (r, g, b, a) in enumerate(lut):
        raw = lo + (hi - lo) * i / (len(lut) - 1)  # normalised v → raw scalar
        color.AddRGBPoint(raw, r, g, b)
        opacity.AddPoint(raw, a)
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)

    step = scene["slice_spacing_voxels"] * unit
    if mapper_kind == "gpu":
        mapper = vtk.vtkGPUVolumeRayCastMapper()
        mapper.LockSampleDistanceToInputSpacingOff()
        mapper.UseJitteringOff()
        if shadows:
            mapper.SetGlobalIlluminationReach(shadows[0])
            mapper.SetVolumetricScatteringBlending(shadows[1])
    elif mapper_kind == "smart":
        mapper = vtk.vtkSmartVolumeMapper()
        mapper.SetRequestedRenderModeToDefault()
        mapper.InteractiveAdjustSampleDistancesOff()
    else:
        mapper = vtk.vtkFixedPointVolumeRayCastMapper()
        if "LP_NUM_THREADS" in os.environ:  # the same CPU budget as llvmpipe
            mapper.SetNumberOfThreads(int(os.environ["LP_NUM_THREADS"]))
    if mapper_kind != "smart":
        mapper.AutoAdjustSampleDistancesOff()
    mapper.SetSampleDistance(step)
    mapper.SetInputData(image)
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)

    ren = vtk.vtkRenderer()
    ren.SetBackground(*scene["background"][:3])
    ren.AddVolume(volume)
    if shading:
        # vwb's k_a scales a white ambient light; VTK's ambient term is k_a times the
        # light's ambient colour, black by default, so without this VTK drops k_a
        # (measured: k_a = 1, k_d = k_s = 0 gave VTK a black image, vwb the unshaded one).
        # The headlight VTK would make by itself, with that one colour set.
        light = vtk.vtkLight()
        light.SetLightTypeToHeadlight()
        light.SetAmbientColor(1.0, 1.0, 1.0)
        ren.AddLight(light)
    rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetSize(img["width"], img["height"])
    rw.AddRenderer(ren)

    w2v = WorldToVtk(vol)
    camera = ren.GetActiveCamera()
    camera.SetPosition(*w2v.point(cam["eye"]))
    camera.SetFocalPoint(*w2v.point(cam["target"]))
    camera.SetViewUp(*cam["up"])
    if cam["projection"] == "perspective":
        camera.ParallelProjectionOff()
        camera.SetViewAngle(cam["fov_y_deg"])
    else:
        camera.ParallelProjectionOn()
        camera.SetParallelScale(0.5 * cam["ortho_height"] * w2v.scale)
    camera.SetClippingRange(cam["near"] * w2v.scale, cam["far"] * w2v.scale)
    return rw, camera, mapper


def read_rgb(rw):
    """The window's pixels as an (h, w, 3) uint8 array, top row first."""
    w, h = rw.GetSize()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(rw)
    grab.SetInputBufferTypeToRGB()
    grab.ShouldRerenderOff()
    grab.Update()
    out = grab.GetOutput()
    px = numpy_support.vtk_to_numpy(out.GetPointData().GetScalars()).reshape(h, w, 3)
    return np.ascontiguousarray(px[::-1])


def time_vtk(rw, camera, frames):
    """Warm-up, one image of the exact view, then `frames` timed renders (ms)."""
    for _ in range(WARMUP):
        rw.Render()
        rw.WaitForCompletion()
    rgb = read_rgb(rw)
    ms = []
    for k in range(frames):
        # Alternate ±jitter so every frame is a real re-render of (nearly) the same view.
        camera.Azimuth(JITTER_DEG if k % 2 == 0 else -JITTER_DEG)
        t0 = time.perf_counter()
        rw.Render()
        rw.WaitForCompletion()
        ms.append((time.perf_counter() - t0) * 1e3)
    return rgb, ms


def gl_renderer(rw):
    m = re.search(r"OpenGL renderer string:\s*(.*)", rw.ReportCapabilities())
    return m.group(1).strip() if m else "?"


def mapper_name(mapper):
    name = mapper.GetClassName()
    if name == "vtkSmartVolumeMapper":
        modes = {mapper.GPURenderMode: "GPU ray cast", mapper.RayCastRenderMode: "CPU ray cast"}
        name += f" ({modes.get(mapper.GetLastUsedRenderMode(), 'undecided')})"
    return name


# ---------------------------------------------------------------------------- main


def compare(vwb_png, vtk_rgb, side_png):
    """Writes vwb | VTK side by side; returns the 8-bit RGB RMS difference (None if sizes differ)."""
    ours = np.asarray(Image.open(vwb_png).convert("RGB"))
    if ours.shape != vtk_rgb.shape:
        return None
    Image.fromarray(np.concatenate([ours, vtk_rgb], axis=1)).save(side_png)
    return rms(ours, vtk_rgb)


def vtk_reference(scene, mapper_kind, shadows=None):
    """VTK's own image at 1/8 of the scene's step (one frame after the warm-up)."""
    fine = with_spacing(scene, scene["slice_spacing_voxels"] / REFERENCE_DIVISOR)
    rw, camera, mapper = build_vtk(fine, mapper_kind, shadows)
    rgb, _ = time_vtk(rw, camera, 0)
    del rw, camera, mapper
    return rgb


def vwb_equal_error(a, scene, n, kind, extra, png, vtk_self, vtk_level, out, env):
    """vwb's self-error for one variant and, when it exceeds VTK's, the coarsest
    refined spacing whose self-error is at most VTK's, timed there; likewise for the
    relative self-error (the self-error over the image's mean 8-bit level), which
    compares renderers whose images differ in brightness (different shading models).

    Returns a dict: self (error at the default spacing), spacing, error and wall at the
    equal-error spacing (the default one when it already qualifies; wall None there),
    level (the mean 8-bit level of vwb's image) and rel, the same for the relative
    self-error (spacing, error, wall)."""
    stem = Path(scene["preset"]).stem
    s0 = scene["slice_spacing_voxels"]
    ref_png = out / f"{stem}_vwb_{n}_{kind}_ref.png"
    # the reference accumulates in f32: 8× the slices in an fp16 eye buffer would add
    # rounding that is not the renderer's at its default step
    vwb_render(a.vwb, with_spacing(scene, s0 / REFERENCE_DIVISOR), kind, 1, ref_png, env,
               [*extra, "--target", "rgba32float"])
    ref = read_png(ref_png)
    own_img = read_png(png)
    own = rms(own_img, ref)
    level = float(own_img.mean())
    # VTK's relative self-error in vwb's 8-bit units
    rel_bound = relative(vtk_self, vtk_level) * level
    found = {"self": own, "spacing": s0, "error": own, "wall": None, "level": level,
             "rel": {"spacing": s0, "error": own, "wall": None}}
    abs_done, rel_done = own <= vtk_self, own <= rel_bound
    for f in REFINE:
        if abs_done and rel_done:
            break
        trial = out / f"{stem}_vwb_{n}_{kind}_refined_{f:g}.png"
        r = vwb_render(a.vwb, with_spacing(scene, s0 / f), kind, a.frames, trial, env, extra)
        err = rms(read_png(trial), ref)
        print(f"  vwb {kind} {' '.join(extra)} spacing {s0 / f:.3g}: self-error {err:.2f}, "
              f"wall {r['wall'][0]:.1f} ms", flush=True)
        if not abs_done:
            found.update(spacing=s0 / f, error=err, wall=r["wall"])
            abs_done = err <= vtk_self
        if not rel_done:
            found["rel"] = {"spacing": s0 / f, "error": err, "wall": r["wall"]}
            rel_done = err <= rel_bound
    found["rel"]["reached"] = found["rel"]["error"] <= rel_bound
    return found


def scene_label(scene):
    dims = "×".join(str(d) for d in scene["volume"]["dims"])
    return f"{Path(scene['preset']).stem} ({dims})"


def setup_env(a):
    """Environment for vwb and (this process) VTK; re-runs under xvfb-run for --gl x."""
    if a.gl == "x" and not os.environ.get("DISPLAY"):
        if not shutil.which("xvfb-run"):
            sys.exit("--gl x needs DISPLAY or xvfb-run")
        os.execvp("xvfb-run", ["xvfb-run", "-a", sys.executable, *sys.argv])
    os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")
    if a.gl == "egl":
        os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
    if not a.gpu:
        os.environ.setdefault("LP_NUM_THREADS", "2")
        os.environ["LIBGL_ALWAYS_SOFTWARE"] = "1"  # VTK: Mesa llvmpipe
    env = dict(os.environ)
    if not a.gpu:
        env.setdefault("VK_DRIVER_FILES", LAVAPIPE_ICD)  # vwb: lavapipe
    return env


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vwb", default=default_vwb(),
                    help="vwb binary (default: target/release/vwb, else target/debug/vwb)")
    ap.add_argument("--preset", action="append",
                    help="preset to compare (repeatable; default: presets/demo.ron and --ct-preset)")
    ap.add_argument("--ct-preset", default="presets/ct_head.ron",
                    help="CT head preset (e.g. a copy whose volume path suits another machine)")
    ap.add_argument("--scene-json", action="append", type=Path,
                    help="scene JSON as `vwb scene` prints it, instead of running it "
                         "(repeatable; replaces --preset, --size and --spacing)")
    ap.add_argument("--size", default="512x512")
    ap.add_argument("--spacing", type=float, help="slice spacing in voxels (default: the preset's)")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=1,
                    help="time VTK and every vwb variant this many times, alternately; the "
                         "ratio is the median of the rounds' ratios (a shared host's load "
                         "drifts between the two renderers' turns within one round less than "
                         "across a run)")
    ap.add_argument("--mapper", choices=("gpu", "smart", "fixed"), default="gpu",
                    help="vtkGPUVolumeRayCastMapper, vtkSmartVolumeMapper or "
                         "vtkFixedPointVolumeRayCastMapper")
    ap.add_argument("--gl", choices=("egl", "x"), default="egl",
                    help="VTK's OpenGL window: EGL offscreen, or GLX (under xvfb-run -a without DISPLAY)")
    ap.add_argument("--gpu", action="store_true",
                    help="let both use the best driver instead of pinning lavapipe/llvmpipe")
    ap.add_argument("-o", "--out", type=Path, help="image folder (default: a new temporary one)")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the block in --doc with the results")
    ap.add_argument("--self-error", action="store_true",
                    help="also each renderer's self-convergence error (its default step against "
                         "1/8 of it) and vwb's speed ratio at VTK's self-error")
    ap.add_argument("--shadows", help="REACH,BLEND: VTK's GPU mapper with volumetric shadows "
                    "(global illumination reach, volumetric scattering blending; shading on), "
                    "against a vwb preset with shade.dos: a different algorithm, so the RMS is "
                    "no check")
    ap.add_argument("--block", default="vtk-peer")
    ap.add_argument("--doc", type=Path, default=REPO / "docs/perf.md")
    a = ap.parse_args()
    shadows = tuple(float(x) for x in a.shadows.split(",")) if a.shadows else None
    if shadows and a.mapper != "gpu":
        sys.exit("--shadows needs --mapper gpu (VTK's volumetric shadows are the GPU mapper's)")
    env = setup_env(a)

    out = a.out or Path(tempfile.mkdtemp(prefix="vwb-vtk-peer-"))
    out.mkdir(parents=True, exist_ok=True)
    if a.scene_json:
        scenes = [json.loads(p.read_text()) for p in a.scene_json]
    else:
        presets = a.preset or ["presets/demo.ron", a.ct_preset]
        scenes = [vwb_scene(a.vwb, p, a.size, a.spacing, env) for p in presets]

    rows, equal, adapter, gl, mapper_used = [], [], "?", "?", "?"
    for scene in scenes:
        label = scene_label(scene)
        stem = Path(scene["preset"]).stem
        img = scene["image"]
        size = f"{img['width']}x{img['height']}"
        vtk_turns, vwb_turns = [], [[] for _ in VWB_VARIANTS]
        for turn in range(a.rounds):
            rw, camera, mapper = build_vtk(scene, a.mapper, shadows)
            vtk_rgb, vtk_ms = time_vtk(rw, camera, a.frames)
            gl, mapper_used = gl_renderer(rw), mapper_name(mapper)
            vtk_png = out / f"{stem}_vtk.png"
            Image.fromarray(vtk_rgb).save(vtk_png)
            vtk_turns.append(stats(vtk_ms))
            v = vtk_turns[-1]
            print(f"{label}: VTK {mapper_used} median {v[0]:.1f} ms (min {v[1]:.1f} max "
                  f"{v[2]:.1f}) → {vtk_png}", flush=True)
            del rw, camera, mapper  # release the GL context before vwb runs
            for n, (backend, kind, extra) in enumerate(VWB_VARIANTS):
                png = out / f"{stem}_vwb_{n}_{kind}.png"
                r = vwb_render(a.vwb, scene, kind, a.frames, png, env, extra)
                vwb_turns[n].append(r)
                print(f"{label}: vwb {backend} wall {r['wall'][0]:.1f} ms (round {turn + 1} of "
                      f"{a.rounds}) → {png}", flush=True)
        v = pooled(vtk_turns)
        vtk_self = rms(vtk_rgb, vtk_reference(scene, a.mapper, shadows)) if a.self_error else None
        vtk_level = float(vtk_rgb.mean())
        if vtk_self is not None:
            print(f"{label}: VTK self-error {vtk_self:.2f}/255", flush=True)
        for n, (backend, kind, extra) in enumerate(VWB_VARIANTS):
            png = out / f"{stem}_vwb_{n}_{kind}.png"
            turns = vwb_turns[n]
            r = turns[-1]
            adapter = r["adapter"]
            ratios = [t["wall"][0] / w[0] for t, w in zip(turns, vtk_turns)]
            wall = pooled([t["wall"] for t in turns])
            diff = compare(png, vtk_rgb, out / f"{stem}_vwb_{n}_{kind}_vs_vtk.png")
            rows.append((label, size, r["slices"], backend, wall,
                         pooled([t["gpu"] for t in turns]), v, stats(ratios), diff))
            shown = "n/a (sizes differ)" if diff is None else f"{diff:.2f}/255"
            print(f"{label}: vwb {backend} vwb/VTK {statistics.median(ratios):.2f}; RMS vs VTK "
                  f"{shown}", flush=True)
            if vtk_self is not None:
                e = vwb_equal_error(a, scene, n, kind, extra, png, vtk_self, vtk_level, out, env)
                e["wall"] = e["wall"] or wall
                e["rel"]["wall"] = e["rel"]["wall"] or wall
                equal.append((label, size, backend, e, vtk_self, vtk_level, v))
                print(f"{label}: vwb {backend} self-error {e['self']:.2f}/255; at spacing "
                      f"{e['spacing']:.3g} {e['error']:.2f}/255, {e['wall'][0]:.1f} ms", flush=True)

    table = [
        "| scene | size | vwb slices | vwb backend | vwb wall ms | vwb GPU ms | VTK ms | vwb/VTK (wall) | RMS vs VTK (8-bit) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, size, slices, backend, wall, gpu, v, ratio, diff in rows:
        shown = f"{ratio[0]:.2f}" if a.rounds == 1 else f"{ratio[0]:.2f} ({ratio[1]:.2f}–{ratio[2]:.2f})"
        table.append(
            f"| {label} | {size} | {slices} | {backend} | {fmt(wall)} | {fmt(gpu)} | {fmt(v)} "
            f"| {shown} | {'n/a' if diff is None else f'{diff:.1f}'} |"
        )
    if equal:
        table += [
            "",
            f"Self-convergence error: each renderer's image at its default step against its own "
            f"image at 1/{REFERENCE_DIVISOR} of that step (RMS, 8-bit RGB; vwb's with an "
            "rgba32float eye buffer). Where vwb's exceeds "
            f"VTK's, vwb's slice spacing is refined (÷{', ÷'.join(f'{f:g}' for f in REFINE)}) "
            "until it does not, and timed there.",
            "",
            "| scene | size | vwb backend | vwb self-error | VTK self-error | vwb spacing at ≤ VTK's self-error (voxels) | vwb self-error there | vwb wall ms there | vwb/VTK at equal self-error |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for label, size, backend, e, vtk_self, _, v in equal:
            reached = "" if e["error"] <= vtk_self else " (not reached)"
            table.append(
                f"| {label} | {size} | {backend} | {e['self']:.2f} | {vtk_self:.2f} "
                f"| {e['spacing']:.3g}{reached} | {e['error']:.2f} | {fmt(e['wall'])} "
                f"| {e['wall'][0] / v[0]:.2f} |"
            )
        table += [
            "",
            "Relative self-convergence error: the self-error over the image's mean 8-bit level "
            "(RGB). Where the two renderers' images differ in brightness (their shading models "
            "differ: the RMS vs VTK column above), equal absolute errors are not equal "
            "accuracy; vwb's slice spacing is refined as above until its relative self-error "
            "is at most VTK's.",
            "",
            "| scene | size | vwb backend | vwb mean level | VTK mean level | vwb relative self-error | VTK relative self-error | vwb spacing at ≤ VTK's relative self-error (voxels) | vwb wall ms there | vwb/VTK at equal relative self-error |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for label, size, backend, e, vtk_self, vtk_level, v in equal:
            rel = e["rel"]
            reached = "" if rel["reached"] else " (not reached)"
            table.append(
                f"| {label} | {size} | {backend} | {e['level']:.1f} | {vtk_level:.1f} "
                f"| {relative(e['self'], e['level']):.4f} | {relative(vtk_self, vtk_level):.4f} "
                f"| {rel['spacing']:.3g}{reached} | {fmt(rel['wall'])} | {rel['wall'][0] / v[0]:.2f} |"
            )
    lp = os.environ.get("LP_NUM_THREADS")
    lines = [
        f"Command: `{shlex.join(['python3', 'bench/vtk_peer.py', *sys.argv[1:]])}`"
        f" — median (min–max) of {a.frames} frames after {WARMUP} warm-up frames, both in one run"
        + ("." if a.rounds == 1 else
           f"; {a.rounds} rounds, VTK and then each vwb variant in each: the times are the median "
           "of the rounds' medians (min–max over every frame), vwb/VTK the median of the rounds' "
           "ratios (min–max over the rounds)."),
        "",
        f"- Machine: {machine_line()}",
        f"- vwb adapter: {adapter}" + (f" (LP_NUM_THREADS={lp})" if not a.gpu else ""),
        f"- VTK {vtk.vtkVersion.GetVTKVersion()}, {mapper_used}, OpenGL renderer: {gl}"
        + (f" (LP_NUM_THREADS={lp})" if not a.gpu else ""),
        "- Same scene from `vwb scene`: volume, camera, 256-entry transfer-function table, "
        "background; VTK samples every slice spacing along each ray (linear interpolation, "
        "opacity unit distance = smallest voxel side; shading on with the preset's k_a, k_d, "
        "k_s and shininess where it has shade.blinn_phong, under a white headlight whose ambient "
        "colour is white too, as vwb's k_a assumes, else off)",
        *([f"- VTK with volumetric shadows: global illumination reach {shadows[0]:g}, volumetric "
           f"scattering blending {shadows[1]:g} (shading on, VTK's default material); vwb with its "
           "preset's shade.dos. Different algorithms: the RMS column is no check"] if shadows else []),
        "",
        *table,
    ]
    block = "\n".join(lines)
    print()
    print(block)
    print(f"\nimages: {out}")
    if a.write_docs:
        write_block(a.doc, a.block, block)
        print(f"rewrote <!-- BEGIN {a.block} --> in {a.doc}")


if __name__ == "__main__":
    main()
