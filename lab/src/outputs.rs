//! Outputs never destroy inputs: every file a command reads (the preset, the volume,
//! a detached NRRD's data file, named volumes such as label volumes, and path
//! parameters) is
//! registered with `vwb_render::files::protect_input`, so every write (all go through
//! `write_atomic`) refuses to replace one; commands also check their `-o` up front.
//! Image formats come from the extension.

use std::path::Path;

use anyhow::{Result, bail};
use vwb_render::files::{check_not_input, protect_input};
use vwb_render::params::ParamValue;
use vwb_render::preset::Document;

/// Registers a volume file and its detached data file as inputs.
pub fn protect_volume(path: &Path) {
    let files = vwb_render::volume::input_files(path);
    for (i, f) in files.iter().enumerate() {
        let role = if i == 0 {
            "volume"
        } else {
            "volume's data file"
        };
        protect_input(role, f);
    }
}

/// Registers everything a document reads: its preset file, its volume and its named
/// volumes (label volumes, fields; with their data files), and file parameters (maps,
/// meshes).
pub fn protect_document(preset: Option<&Path>, doc: &Document) {
    if let Some(p) = preset {
        protect_input("preset", p);
    }
    for source in std::iter::once(&doc.volume).chain(doc.volumes.values()) {
        if let Some(v) = source.file() {
            protect_volume(v);
        }
    }
    for inst in &doc.stack {
        for v in inst.params.values.values() {
            if let ParamValue::Path(p) = v
                && !p.as_os_str().is_empty()
            {
                protect_volume(p);
            }
        }
    }
}

/// Fails when `output` is a registered input, naming both.
pub fn check_output(output: &Path) -> Result<()> {
    check_not_input(output).map_err(|e| anyhow::anyhow!("{}: {e}", output.display()))
}

/// The image format an output path asks for: `.png`, or `.jpg`/`.jpeg`; anything
/// else is refused, so a `.jpg` never holds PNG bytes.
pub fn image_format(path: &Path) -> Result<image::ImageFormat> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("png") => Ok(image::ImageFormat::Png),
        Some("jpg" | "jpeg") => Ok(image::ImageFormat::Jpeg),
        Some(other) => bail!(
            "{}: cannot write .{other} images; use a .png (lossless) or .jpg name",
            path.display()
        ),
        None => bail!(
            "{}: no file extension; use a .png (lossless) or .jpg name",
            path.display()
        ),
    }
}

/// Text outputs are named for what they hold: an output whose extension is not
/// `ext` (e.g. `bench -o out.png`) is refused rather than filled with CSV.
pub fn check_extension(path: &Path, ext: &str, what: &str) -> Result<()> {
    let got = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if got.as_deref() == Some(ext) {
        Ok(())
    } else {
        bail!(
            "{}: this command writes {what}; name the output .{ext}",
            path.display()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_come_from_the_extension() {
        assert_eq!(
            image_format(Path::new("a/b.PNG")).unwrap(),
            image::ImageFormat::Png
        );
        assert_eq!(
            image_format(Path::new("b.jpeg")).unwrap(),
            image::ImageFormat::Jpeg
        );
        let e = image_format(Path::new("p.ron")).unwrap_err().to_string();
        assert!(e.contains("p.ron") && e.contains(".ron images"), "{e}");
        assert!(image_format(Path::new("noext")).is_err());
        assert!(check_extension(Path::new("b.CSV"), "csv", "CSV").is_ok());
        let e = check_extension(Path::new("b.png"), "csv", "CSV")
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.png") && e.contains(".csv"), "{e}");
    }
}
