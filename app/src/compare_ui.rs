//! The window's compare view: the current GPU image beside a CPU reference computed in
//! a background thread with progress and cancel, the ΔE*uv heatmap and the metrics.
//! The reference is either the twin of the same stack, camera and slices
//! (`vwb_render::reference`: is the GPU doing what the plugins say?) or the converged
//! one (`vwb_lab::measure::converged_image`: refined slices, or the Monte-Carlo cone
//! integral for directional occlusion: how far is this frame from the integral?).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use vwb_render::metrics::{Metrics, RgbImageF, compare, delta_e_map, heatmap};
use vwb_render::reference::{ReferenceOptions, render_reference};
use vwb_render::renderer::FrameSettings;
use vwb_render::{PluginInstance, TargetFormat, Volume};

use vwb_lab::job::Job;

/// What the compare view shows once the reference is done.
pub struct Comparison {
    pub metrics: Metrics,
    pub gpu: image::RgbImage,
    pub reference: image::RgbImage,
    pub heatmap: image::RgbImage,
}

/// A reference being computed.
pub struct CompareJob {
    progress: Arc<AtomicUsize>,
    cancel: Arc<AtomicBool>,
    /// Rows of the same-slices reference; unknown for the converged one.
    rows: Option<u32>,
    job: Job<Comparison>,
}

/// What the compare view compares against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Against {
    /// The CPU twin with the same slices.
    #[default]
    SameSlices,
    /// The converged reference (Monte Carlo for stacks with directional occlusion).
    Converged,
}

fn finish(gpu: &RgbImageF, reference: RgbImageF) -> Comparison {
    let metrics = compare(gpu, &reference);
    let map = delta_e_map(gpu, &reference);
    Comparison {
        heatmap: heatmap(&map, reference.width, reference.height, metrics.max_delta_e),
        gpu: gpu.to_rgb8(),
        reference: reference.to_rgb8(),
        metrics,
    }
}

impl CompareJob {
    /// Starts the reference of `stack` for `settings` in a thread; `gpu` is the GPU
    /// image of the same frame composited over `background`.
    pub fn start(
        volume: Arc<Volume>,
        inputs: vwb_render::inputs::VolumeInputs,
        stack: Vec<PluginInstance>,
        settings: FrameSettings,
        target: TargetFormat,
        gpu: RgbImageF,
        background: [f64; 3],
    ) -> Self {
        let progress = Arc::new(AtomicUsize::new(0));
        let cancel = Arc::new(AtomicBool::new(false));
        let opts = ReferenceOptions {
            emulate_fp16: target == TargetFormat::Rgba16Float,
            progress: Some(progress.clone()),
            cancel: Some(cancel.clone()),
            inputs,
        };
        let job = Job::spawn("reference", move || {
            render_reference(&volume, &stack, &settings, &opts)
                .map_err(|e| e.to_string())
                .map(|r| {
                    let reference = RgbImageF::from_rgba_premultiplied_over(
                        &r.pixels, r.width, r.height, background,
                    );
                    finish(&gpu, reference)
                })
        });
        Self {
            progress,
            cancel,
            rows: Some(settings.height),
            job,
        }
    }

    /// Starts the converged reference of `doc` for `settings` in a thread
    /// ([`vwb_lab::measure::converged_image`], tolerance in RMS ΔE*uv).
    pub fn start_converged(
        volume: Arc<Volume>,
        doc: vwb_render::preset::Document,
        settings: FrameSettings,
        gpu: RgbImageF,
        tolerance: f64,
    ) -> Self {
        let progress = Arc::new(AtomicUsize::new(0));
        let cancel = Arc::new(AtomicBool::new(false));
        let opts = ReferenceOptions {
            progress: Some(progress.clone()),
            cancel: Some(cancel.clone()),
            ..Default::default()
        };
        let job = Job::spawn("reference", move || {
            vwb_lab::measure::converged_image(&volume, &doc, &settings, tolerance, &opts)
                .map_err(|e| format!("{e:#}"))
                .map(|(reference, _)| finish(&gpu, reference))
        });
        Self {
            progress,
            cancel,
            rows: None,
            job,
        }
    }

    /// Share of the rows done; `None` while converging (the number of refinement
    /// passes is not known in advance).
    pub fn fraction(&self) -> Option<f32> {
        self.rows
            .map(|rows| self.progress.load(Ordering::Relaxed) as f32 / rows.max(1) as f32)
    }

    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// The result once the thread has finished.
    pub fn poll(&self) -> Option<Result<Comparison, String>> {
        self.job.poll()
    }
}

/// An 8-bit image as an egui image.
pub fn color_image(img: &image::RgbImage) -> egui::ColorImage {
    egui::ColorImage::from_rgb([img.width() as usize, img.height() as usize], img.as_raw())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vwb_render::{Backend, GpuContext, Renderer};

    fn wait(job: &CompareJob) -> Result<Comparison, String> {
        loop {
            if let Some(r) = job.poll() {
                return r;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
    }

    /// The GPU image of the demo against its reference: the compute backend agrees
    /// (as the presets test checks); a cancelled job says so.
    #[test]
    fn reference_in_the_background_and_cancel() {
        let gpu = GpuContext::new_headless().expect("a Vulkan adapter (lavapipe is fine)");
        let volume = Arc::new(vwb_render::volume::demo());
        let stack = vec![PluginInstance::new(
            vwb_plugins::builtin_registry()
                .get("classify.tf1d")
                .unwrap(),
        )];
        let settings = FrameSettings {
            width: 40,
            height: 32,
            backend: Backend::Compute,
            ..Default::default()
        };
        let mut r = Renderer::new(&gpu, volume.clone()).unwrap();
        r.update_stack(&stack, TargetFormat::Rgba32Float).unwrap();
        r.render(&settings).unwrap();
        let (w, h, px) = r.read_pixels().unwrap();
        let bg = [0.0; 3];
        let image = RgbImageF::from_rgba_f32_premultiplied_over(&px, w, h, bg);
        let job = CompareJob::start(
            volume.clone(),
            Default::default(),
            stack.clone(),
            settings,
            TargetFormat::Rgba32Float,
            image.clone(),
            bg,
        );
        let c = wait(&job).unwrap();
        assert!(c.metrics.rms_delta_e < 0.15, "{}", c.metrics.rms_delta_e);
        assert!((job.fraction().unwrap() - 1.0).abs() < 1e-6);
        // the heatmap carries its colour bar beside the image
        assert!(c.heatmap.width() > 40 && c.heatmap.height() == 32);
        assert_eq!(color_image(&c.reference).size, [40, 32]);

        let big = FrameSettings {
            width: 1024,
            height: 1024,
            ..settings
        };
        let gpu_big = RgbImageF::new(1024, 1024, vec![[0.0; 3]; 1024 * 1024]);
        let job = CompareJob::start(
            volume.clone(),
            Default::default(),
            stack.clone(),
            big,
            TargetFormat::Rgba32Float,
            gpu_big,
            bg,
        );
        job.cancel();
        let e = wait(&job).err().expect("cancelled");
        assert!(e.to_lowercase().contains("cancel"), "{e}");

        // against the converged reference the error is larger than against the same
        // slices (the slices' own discretisation error shows), but still small
        let mut doc = vwb_lab::document::default_document(&vwb_plugins::builtin_registry());
        doc.stack = stack;
        doc.render.background = [0.0, 0.0, 0.0, 1.0];
        let job = CompareJob::start_converged(volume, doc, settings, image, 0.5);
        assert!(job.fraction().is_none());
        let conv = wait(&job).unwrap();
        assert!(
            conv.metrics.rms_delta_e > c.metrics.rms_delta_e && conv.metrics.rms_delta_e < 10.0,
            "converged {} vs same slices {}",
            conv.metrics.rms_delta_e,
            c.metrics.rms_delta_e
        );
    }
}
