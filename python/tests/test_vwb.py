"""The Python package on the CPU Vulkan device (lavapipe) or a GPU: render a preset to
NumPy, change a parameter, compare against the converged reference, time a frame, run
an experiment file, and refuse bad input with a clear error."""

from pathlib import Path

import numpy as np
import pytest

import vwb

REPO = Path(__file__).resolve().parents[2]
DEMO = str(REPO / "presets" / "demo_preintegrated.ron")


def test_adapter_is_vulkan():
    assert "Vulkan" in vwb.adapter()


def test_render_to_numpy():
    s = vwb.Scene(DEMO)
    img = s.render(size=(48, 40))
    assert img.shape == (40, 48, 3)
    assert img.dtype == np.float32
    assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() <= 1.0
    assert img.mean() > 0.02, "the head is visible"
    # same scene, same image
    assert vwb.compare(img, s.render(size=(48, 40)))["rms_delta_e"] == 0.0


def test_parameters_change_the_image_and_bad_ones_are_refused():
    s = vwb.Scene(DEMO)  # pre-integrated in the preset
    s.set("classify.tf1d.mode", "post")
    post = s.render(size=(40, 40), spacing=2.0)
    s.set("classify.tf1d.mode", "preintegrated")
    pre = s.render(size=(40, 40), spacing=2.0)
    s.set("classify.tf1d.mode", "post")
    again = s.render(size=(40, 40), spacing=2.0)
    assert vwb.compare(post, again)["rms_delta_e"] == 0.0, "setting it back restores the image"
    assert vwb.compare(pre, post)["rms_delta_e"] > 0.1, "pre-integration changes the image"
    with pytest.raises(ValueError, match="no parameter 'nope'"):
        s.set("classify.tf1d.nope", 1.0)
    with pytest.raises(ValueError, match="mode"):
        s.set("classify.tf1d.mode", "sideways")
    with pytest.raises(ValueError, match="> 0"):
        s.render(size=(16, 16), spacing=-1.0)
    with pytest.raises(RuntimeError, match="nonexistent.ron"):
        vwb.Scene("nonexistent.ron")


def moved_and_back(key, value, bound, why):
    """A scene whose render setting `key` set to `value` moves the image by less than
    `bound` (RMS ΔE*uv) but not by nothing, and set back to auto gives the image again;
    returns the scene and that image."""
    s = vwb.Scene(DEMO)
    full = s.render(size=(40, 40))
    s.set(key, value)
    moved = s.render(size=(40, 40))
    assert 0.0 < vwb.compare(full, moved)["rms_delta_e"] < bound, why
    s.set(key, "auto")
    assert vwb.compare(full, s.render(size=(40, 40)))["rms_delta_e"] == 0.0
    return s, full


def test_volume_format_is_a_render_setting():
    s, full = moved_and_back("render.volume_format", "r16float", 0.5, "11-bit values, nearly the image")
    s.set("render.volume_format", "r8unorm")
    byte = s.render(size=(40, 40))
    assert 0.0 < vwb.compare(full, byte)["rms_delta_e"] < 1.0, "1/255 steps, nearly the image"
    with pytest.raises(ValueError, match="r4unorm"):
        s.set("render.volume_format", "r4unorm")


def test_table_format_is_a_render_setting():
    s, _ = moved_and_back("render.table_format", "rgba16float", 0.2, "half-float tables, nearly the image")
    with pytest.raises(ValueError, match="rgba8unorm"):
        s.set("render.table_format", "rgba8unorm")


def test_vector_parameters_are_set_from_sequences():
    s = vwb.Scene(str(REPO / "presets" / "demo_dos.ron"))
    grey = s.render(size=(32, 32))
    s.set("shade.dos.extinction", "chromatic")
    s.set("shade.dos.extinction_rgb", (1.0, 1.0, 1.0))
    assert vwb.compare(grey, s.render(size=(32, 32)))["rms_delta_e"] < 1e-3, "κ = 1 is achromatic"
    s.set("shade.dos.extinction_rgb", [0.4, 1.0, 2.5])
    assert vwb.compare(grey, s.render(size=(32, 32)))["rms_delta_e"] > 0.1, "warm shadows"
    with pytest.raises(ValueError, match="does not fit"):
        s.set("shade.dos.extinction_rgb", (1.0, 2.0))
    with pytest.raises(ValueError, match="outside"):
        s.set("shade.dos.extinction_rgb", (1.0, 2.0, 9.0))


def test_finer_slices_are_closer_to_the_converged_reference():
    s = vwb.Scene(DEMO)
    s.set("classify.tf1d.mode", "post")
    ref = s.converged(size=(32, 32), tolerance=0.5)
    fine = vwb.compare(s.render(size=(32, 32), spacing=0.5), ref)
    coarse = vwb.compare(s.render(size=(32, 32), spacing=4.0), ref)
    assert fine["rms_delta_e"] < coarse["rms_delta_e"]
    t = s.time(size=(32, 32), spacing=1.0, frames=2)
    assert t["frame_ms"] > 0 and t["slices"] > 10


def test_run_experiment_returns_rows(tmp_path):
    exp = tmp_path / "e.ron"
    exp.write_text(
        f'''Experiment(name: "py", scenes: [Preset("{DEMO}")],
            variants: [(name: "post", set: {{"classify.tf1d.mode": "post"}})],
            grid: [(param: "render.slice_spacing", values: [1.0, 2.0])],
            reference: Twin, render: (size: (24, 24)), frames: 1,
            assertions: ["slices > 5"])'''
    )
    rows = vwb.run_experiment(str(exp), out=str(tmp_path / "out"))
    assert [r["values"] for r in rows] == [[1.0], [2.0]]
    assert rows[0]["slices"] > rows[1]["slices"]
    assert (tmp_path / "out" / "junit.xml").is_file()
    bad = tmp_path / "bad.ron"
    bad.write_text(exp.read_text().replace("slices > 5", "slices > 100000"))
    with pytest.raises(RuntimeError, match="assertions failed"):
        vwb.run_experiment(str(bad), out=str(tmp_path / "out2"))


def test_a_named_volume_feeds_a_plugin_input(tmp_path):
    preset = tmp_path / "named.ron"
    preset.write_text(
        """(version: 1, volume: Analytic((field: Abc, size: (24, 20, 12))),
           volumes: {"turn": Analytic((field: Rotation, size: (12, 10, 12)))},
           render: (size: (32, 32), backend: Compute),
           plugins: [(id: "flow.lic3d", params: {"length": 4.0}), (id: "classify.tf1d")])"""
    )
    s = vwb.Scene(str(preset))
    own = s.render(size=(32, 32))
    s.set("flow.lic3d.field", "turn")
    turned = s.render(size=(32, 32))
    assert vwb.compare(own, turned)["rms_delta_e"] > 0.5, "another field, another LIC"
    s.set("flow.lic3d.field", "")
    assert vwb.compare(own, s.render(size=(32, 32)))["rms_delta_e"] == 0.0
    s.set("flow.lic3d.field", "gust")
    with pytest.raises(Exception, match="no volume named 'gust'"):
        s.render(size=(32, 32))


def test_a_label_volume_added_by_name_classifies_the_scene():
    labels = str(REPO / "presets" / "data" / "demo_labels.nrrd")
    s = vwb.Scene(str(REPO / "presets" / "demo_labels.ron"))
    shipped = s.render(size=(40, 40))
    assert s.add_volume(labels, name="seg") == "seg"
    vols = s.volumes()
    assert set(vols) == {"labels", "seg"} and vols["seg"][1] == 1
    assert vols["seg"][0] == vols["labels"][0]
    s.set("classify.labels.labels", "seg")
    assert vwb.compare(shipped, s.render(size=(40, 40)))["rms_delta_e"] == 0.0, "the same labels"
    s.set("classify.labels.labels", "")  # the demo itself read as labels: another image
    assert vwb.compare(shipped, s.render(size=(40, 40)))["rms_delta_e"] > 0.5
    with pytest.raises(ValueError, match="already has a volume named 'seg'"):
        s.add_volume(labels, name="seg")
    with pytest.raises(ValueError, match="not a volume name"):
        s.add_volume(labels, name="1st")
    with pytest.raises(ValueError, match="absent.nrrd"):
        s.add_volume("/nonexistent/absent.nrrd")
    assert set(s.volumes()) == {"labels", "seg"}, "a refused volume changes nothing"


def test_a_user_plugin_loads_swaps_in_and_renders(tmp_path):
    ids = vwb.load_plugins(str(REPO / "examples" / "plugins" / "gooch"))
    assert "shade.gooch" in ids
    s = vwb.Scene(str(REPO / "presets" / "demo_shaded.ron"))
    phong = s.render(size=(32, 32))
    s.add("shade.gooch", replace="shade.blinn_phong")
    assert "shade.gooch" in s.plugins() and "shade.blinn_phong" not in s.plugins()
    gooch = s.render(size=(32, 32))
    assert vwb.compare(phong, gooch)["rms_delta_e"] > 0.5, "another shading model"
    s.set("shade.gooch.beta", 0.0)
    assert vwb.compare(gooch, s.render(size=(32, 32)))["rms_delta_e"] > 0.05
    s.remove("shade.gooch")
    assert "shade.gooch" not in s.plugins()
    with pytest.raises(ValueError, match="shade.nothing"):
        s.add("shade.nothing")
    # a broken copy is refused with its file and line
    broken = tmp_path / "broken"
    broken.mkdir()
    src = REPO / "examples" / "plugins" / "gooch"
    (broken / "plugin.ron").write_text((src / "plugin.ron").read_text().replace("shade.gooch", "shade.gooch_broken"))
    (broken / "gooch.wgsl").write_text((src / "gooch.wgsl").read_text().replace("let k =", "let k = ="))
    with pytest.raises(ValueError, match=r"gooch\.wgsl:\d+"):
        vwb.load_plugins(str(broken))
