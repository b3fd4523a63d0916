//! The window's side of sample data: volumes are loaded through [`FetchOffer::load`],
//! which remembers a missing sample; the side panel then offers a button that runs
//! `vwb data fetch NAME` in the background ([`vwb_lab::job::Job`]) and opens the preset
//! again once the files are there and verified.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Result;
use vwb_render::Volume;
use vwb_render::preset::VolumeSource;
use vwb_render::samples::{self, SampleError};

use crate::data_cmd::{self, Source};
use vwb_lab::headless;
use vwb_lab::job::Job;

/// The sample a load failed for, if a missing sample was the cause.
pub fn missing_sample(err: &anyhow::Error) -> Option<String> {
    err.chain()
        .find_map(|e| e.downcast_ref::<SampleError>())
        .and_then(|e| match e {
            SampleError::Missing { name, .. } => Some(name.clone()),
            _ => None,
        })
}

#[derive(Default)]
pub struct FetchOffer {
    /// The data directory; `None`: [`samples::data_dir`].
    pub dir: Option<PathBuf>,
    /// The missing sample and the file to open again once it is fetched.
    pending: Option<(String, PathBuf)>,
    job: Option<Job<String>>,
    /// The last fetch's failure.
    failed: Option<String>,
}

impl FetchOffer {
    fn data_dir(&self) -> Result<PathBuf> {
        match &self.dir {
            Some(d) => Ok(d.clone()),
            None => Ok(samples::data_dir()?),
        }
    }

    /// Loads the volume `src` names, for the file `opening` (a preset or a volume), for
    /// a renderer with the GPU memory `budget` (an OME-Zarr image reads only the stored
    /// level that fits); a missing sample is remembered and offered for fetching.
    pub fn load(
        &mut self,
        src: &VolumeSource,
        opening: &Path,
        budget: Option<u64>,
    ) -> Result<Arc<Volume>> {
        let result = match src {
            VolumeSource::Sample(name) => (|| {
                let sample = samples::manifest().get(name)?;
                let path = samples::resolve_in(sample, &self.data_dir()?)?;
                Ok(Arc::new(headless::load_volume_file_within(&path, budget)?))
            })(),
            other => headless::load_volume_within(other, budget),
        };
        match &result {
            Err(e) => self.offer(e, opening),
            // an older offer is moot once something else opened
            Ok(_) if self.job.is_none() => self.pending = None,
            Ok(_) => {}
        }
        result
    }

    /// Offers a fetch when `err` is a missing sample (and forgets any older offer).
    pub fn offer(&mut self, err: &anyhow::Error, opening: &Path) {
        self.pending = missing_sample(err).map(|name| (name, opening.to_path_buf()));
        self.failed = None;
    }

    /// The fetch button, the running fetch and its failure. Returns the file to open
    /// again after a successful fetch.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<PathBuf> {
        let (name, retry) = self.pending.clone()?;
        if let Some(job) = &self.job {
            match job.poll() {
                None => {
                    ui.horizontal(|ui| {
                        ui.spinner();
                        ui.label(format!("fetching {name}…"));
                    });
                    ui.ctx().request_repaint();
                    return None;
                }
                Some(Ok(_)) => {
                    self.job = None;
                    self.pending = None;
                    return Some(retry);
                }
                Some(Err(e)) => {
                    self.job = None;
                    self.failed = Some(e);
                }
            }
        }
        let dir = self.data_dir();
        let hover = match &dir {
            Ok(d) => format!(
                "runs `vwb data fetch {name}` in the background: downloads the files into {}, checks their SHA-256 and opens {} again",
                d.display(),
                retry.display()
            ),
            Err(e) => format!("{e:#}"),
        };
        if ui
            .button(format!("Fetch {name}"))
            .on_hover_text(hover)
            .clicked()
        {
            match dir {
                Ok(dir) => {
                    let source = Source::from_args(None);
                    self.failed = None;
                    self.job = Some(Job::spawn("data fetch", move || {
                        let sample = samples::manifest().get(&name).map_err(|e| e.to_string())?;
                        data_cmd::fetch_sample(sample, &dir, source.as_ref())
                            .map_err(|e| format!("{e:#}"))
                    }));
                }
                Err(e) => self.failed = Some(format!("{e:#}")),
            }
        }
        if let Some(e) = &self.failed {
            ui.colored_label(egui::Color32::RED, e);
        }
        None
    }
}
