//! Worked examples shown under `vwb --help` and each subcommand's help (clap
//! `after_help`). Every line that starts with `vwb ` is a complete command that the
//! tests parse with the real argument parser.

pub const VWB: &str = "\
Examples:
  # the window on the embedded demo (an MRI head)
  vwb
  # the window on a preset; its sample data set comes from `vwb data fetch ct_head`
  vwb --preset presets/ct_head.ron
  # headless: render a preset to a PNG
  vwb render --preset presets/demo.ron -o demo.png
  # which sample data sets are present
  vwb data list
  # user plugins (a folder with plugin.ron and WGSL) next to the built-in ones
  vwb --plugins examples/plugins --preset presets/demo_shaded.ron";

pub const RENDER: &str = "\
Examples:
  vwb render --preset presets/demo.ron --size 256x256 -o demo.png
  # the CT head on the compute backend, with per-frame timings
  vwb render --preset presets/ct_head.ron --backend compute --timings -o ct.png
  # another volume (a file or a sample name) under the same preset
  vwb render --preset presets/nuclei.ron --volume nuclei --spacing 0.5 -o nuclei.png";

pub const CROP: &str = "\
Examples:
  # the part of the CT head the preset's clip shapes keep
  vwb crop --preset presets/ct_clip_quadrant.ron -o ct_part.nhdr
  # a voxel box x0,y0,z0,x1,y1,z1 (upper bounds exclusive)
  vwb crop --preset presets/ct_head.ron --box 64,64,20,192,192,90 -o ct_box.nhdr";

pub const COMPARE: &str = "\
Examples:
  # against the CPU reference with the same slices
  vwb compare --preset presets/demo.ron -o out/compare
  # against the converged reference (how far from the exact image)
  vwb compare --preset presets/demo.ron --against converged --size 128x128 -o out/converged";

pub const BENCH: &str = "\
Example:
  vwb bench --preset presets/ct_shade_phong.ron --frames 10 -o bench.csv";

pub const SWEEP: &str = "\
Example:
  # three slice spacings and two opacity scales: time and error of each
  vwb sweep --preset presets/demo.ron --param render.slice_spacing=0.5..2:3:log --param classify.tf1d.opacity=0.5,1 -o out/sweep";

pub const SCENE: &str = "\
Example:
  vwb scene --preset presets/ct_head.ron --size 256x256";

pub const SUGGEST_TF: &str = "\
Examples:
  # a sample by name, or a volume file
  vwb suggest-tf --volume ct_head -o ct_tf.ron
  vwb suggest-tf --max-opacity 0.3 -o demo_tf.ron";

pub const GALLERY: &str = "\
Examples:
  # 36 dispersed TFs for the CT head out of 256 random ones, from 3 viewpoints
  vwb gallery --preset presets/ct_head.ron -o out/gallery
  # refine around pick 4 of that gallery, with a smaller mutation radius
  vwb gallery --preset presets/ct_head.ron --around out/gallery/genomes.ron --pick 4 --radius 0.2 -o out/refined
  # save the preset with pick 2's TF
  vwb gallery --preset presets/ct_head.ron --around out/refined/genomes.ron --pick 2 --apply -o ct_picked.ron";

pub const EVOLVE: &str = "\
Examples:
  # search the demo's TF space for the pre-integrated demo's look, 20 generations of 32
  vwb evolve --preset presets/demo.ron --target-preset presets/demo_preintegrated.ron --seed 1 -o out/evolve
  # or for the TF whose images show the most edges
  vwb evolve --preset presets/ct_head.ron --objective edge_energy --seed 1 -o out/edges
  # or for the TF that shows each boundary of the data, without fog
  vwb evolve --preset presets/ct_head.ron --objective boundary_coverage --seed 1 -o out/boundaries
  # toward an image: the three views side by side (here the first run's target)
  vwb evolve --preset presets/demo.ron --target out/evolve/target.png --seed 2 -o out/from_image";

pub const ADAPT_TF: &str = "\
Example:
  # the CT head's TF moved onto another scan's value distribution
  vwb adapt-tf --reference-volume ct_head --tf ct_tf.ron --volume other_ct.nii.gz -o other_tf.ron";

pub const RUN: &str = "\
Examples:
  # regenerate the classification table in docs/classification.md
  vwb run experiments/classification.ron
  # regenerate docs/dos.md (directional occlusion: six experiment files)
  vwb run experiments/dos*.ron
  # a quick check of the illumination models, report into a chosen folder
  vwb run experiments/shading_switchboard.ron -o out/shading";

pub const INFO: &str = "\
Examples:
  vwb info
  # what a volume file holds: dims, type, spacing, orientation, range, warnings
  vwb info --volume brain.nii.gz
  vwb info --volume ct_head";

pub const DATA: &str = "\
Examples:
  vwb data list
  # mri_head comes from the binary itself
  vwb data fetch mri_head
  # the others from a mirror of the sample files: a URL or a folder
  vwb data fetch --from https://mirror.example.org/vwb-data ct_head nuclei
  vwb data fetch --from /mnt/lab/vwb-data";

pub const DATA_LIST: &str = "\
Example:
  # the data directory is $VWB_DATA_DIR, else the user's cache + vwb/data
  vwb data list";

pub const DATA_FETCH: &str = "\
Examples:
  vwb data fetch mri_head
  vwb data fetch --from https://mirror.example.org/vwb-data ct_head
  # an interrupted download resumes when the same command runs again
  vwb data fetch --from /mnt/lab/vwb-data";
