//! Volumes that load off the UI thread: pipes, FIFOs and devices (which may block), and
//! files of at least `Workbench::async_load_bytes`, with a progress bar and Cancel.
//! Small files load at once, so the window never flickers a progress bar for them.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::Instant;

use vwb_render::Volume;
use vwb_render::volume::LoadProgress;

use vwb_lab::job::Job;

/// Files at least this large (with a detached NRRD's data file) load in the background.
pub const DEFAULT_ASYNC_LOAD_BYTES: u64 = 64 << 20;

pub struct VolumeLoad {
    pub path: PathBuf,
    /// The preset being opened with this volume (its path and document), if any.
    pub preset: Option<(PathBuf, vwb_render::preset::Document)>,
    job: Job<Arc<Volume>>,
    progress: Arc<LoadProgress>,
    started: Instant,
}

impl VolumeLoad {
    /// Whether `path` should load in the background: a pipe, FIFO or device, or
    /// `threshold` bytes or more on disk (with a detached data file, the DICOM files of
    /// a series or the pages of a TIFF folder). Missing files and folders without
    /// volume files load at once (and fail with their message).
    pub fn wanted(path: &Path, threshold: u64) -> bool {
        match std::fs::metadata(path) {
            Ok(m) if !m.is_file() && !m.is_dir() => true,
            Ok(_) => {
                let bytes: u64 = vwb_render::volume::input_files(path)
                    .iter()
                    .filter_map(|f| std::fs::metadata(f).ok())
                    .map(|m| m.len())
                    .sum();
                bytes >= threshold
            }
            Err(_) => false,
        }
    }

    /// Starts loading `path` in a thread (registered as an input, like every volume);
    /// under a GPU memory budget an OME-Zarr image reads only the stored level that
    /// fits ([`vwb_render::volume::load_for_budget`]).
    pub fn start(path: &Path, budget: Option<u64>) -> Self {
        vwb_lab::outputs::protect_volume(path);
        let progress = Arc::new(LoadProgress::default());
        let p = progress.clone();
        let owned = path.to_path_buf();
        let job = Job::spawn("volume loading", move || {
            vwb_render::volume::with_progress(p, || {
                vwb_render::volume::load_for_budget(&owned, budget)
            })
            .map(Arc::new)
            .map_err(|e| e.to_string())
        });
        Self {
            path: path.to_path_buf(),
            preset: None,
            job,
            progress,
            started: Instant::now(),
        }
    }

    /// The volume or the error once the thread has finished.
    pub fn poll(&self) -> Option<Result<Arc<Volume>, String>> {
        self.job.poll()
    }

    /// Asks the thread to stop (it does between chunks); its result is dropped.
    pub fn cancel(&self) {
        self.progress.cancel.store(true, Relaxed);
    }

    /// The progress bar and a Cancel button; `true` when Cancel was clicked.
    pub fn ui(&self, ui: &mut egui::Ui) -> bool {
        let name = self.path.file_name().map_or_else(
            || self.path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        let mut cancel = false;
        ui.horizontal(|ui| {
            let total = self.progress.total.load(Relaxed);
            let text = if total == 0 {
                format!(
                    "loading {name}… {:.1} s",
                    self.started.elapsed().as_secs_f32()
                )
            } else {
                format!(
                    "loading {name}: {:.0} of {:.0} MB",
                    self.progress.done.load(Relaxed) as f64 / 1e6,
                    total as f64 / 1e6
                )
            };
            ui.add(
                egui::ProgressBar::new(self.progress.fraction())
                    .desired_width(160.0)
                    .text(text),
            );
            cancel = ui.button("Cancel").clicked();
        });
        cancel
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_files_and_streams_load_in_the_background() {
        let d = std::env::temp_dir().join(format!("vwb-loading-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("v.nrrd");
        std::fs::write(&f, vec![0u8; 1000]).unwrap();
        assert!(VolumeLoad::wanted(&f, 1000));
        assert!(!VolumeLoad::wanted(&f, 1001));
        assert!(!VolumeLoad::wanted(&d.join("missing"), 0));
        // a DICOM series counts all its files, opened by folder or by one file
        let series = d.join("series");
        std::fs::create_dir_all(&series).unwrap();
        for k in 0..3 {
            vwb_render::volume::dicom::write_slice(
                &series.join(format!("s{k}")),
                &vwb_render::volume::dicom::SliceSpec {
                    instance: k + 1,
                    rows: 16,
                    cols: 16,
                    samples: &[0; 256],
                    positions: &[[0.0, 0.0, f64::from(k)]],
                    ..Default::default()
                },
            )
            .unwrap();
        }
        let one = std::fs::metadata(series.join("s0")).unwrap().len();
        assert!(one > 512, "{one}");
        for path in [series.clone(), series.join("s1")] {
            assert!(VolumeLoad::wanted(&path, 3 * one), "{path:?}");
            assert!(!VolumeLoad::wanted(&path, 3 * one + 1), "{path:?}");
        }
        // a folder without volume files loads at once (and fails with its message)
        assert!(!VolumeLoad::wanted(&d.join("series/../missing-folder"), 0));
        let empty = d.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(!VolumeLoad::wanted(&empty, 1));
        #[cfg(unix)]
        assert!(VolumeLoad::wanted(Path::new("/dev/null"), u64::MAX));
    }
}
