//! Many views or variants in one submission: an atlas of tiles, each a camera and a
//! plugin stack of the same structure (e.g. transfer-function variants seen from a few
//! viewpoints, for galleries and genetic search).
//!
//! All tiles share the compiled stack (one composition, one set of pipelines); each
//! tile's instances keep their own uniforms and resources (a variant's lookup table),
//! each tile gets its own frame uniform and group-0 bind group, and the tiles are drawn
//! one after another into the eye buffer and copied into the atlas texture inside one
//! command encoder, submitted once. A stack's volume passes run once per variant; its
//! view passes (those that read the camera) run again before each tile whose camera
//! differs from the last one they ran with. Under per-slice state (`shade.dos`) each
//! tile runs its slice dispatches in turn, its state cleared first. The images are those of
//! [`Renderer::render`] with the same settings, tile by tile (tested).

use super::*;

/// One tile of an atlas: the camera it is seen from and the stack that draws it.
#[derive(Clone, Copy)]
pub struct AtlasTile<'a> {
    pub camera: Camera,
    pub stack: &'a [PluginInstance],
}

/// An atlas of `cols` × `rows` tiles of `tile` pixels, tile i at column i % cols and
/// row i / cols; premultiplied RGBA, row-major over the whole atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct Atlas {
    pub cols: u32,
    pub rows: u32,
    pub tile: [u32; 2],
    pub tiles: usize,
    pub pixels: Vec<[f32; 4]>,
    /// Wall time from encoding to the GPU finishing, ms.
    pub wall_ms: f64,
    /// Pre-passes the atlas ran.
    pub prepasses_run: usize,
    /// Volume-pass dispatches the atlas ran (each tile stack's out-of-date passes).
    pub volume_passes_run: usize,
    /// On a CPU device: the invocations whose loops ran out of llvmpipe's loop
    /// iterations in the atlas returned, so that their rays may be cut short
    /// ([`Renderer::render_atlas`] renders again in smaller parts first, as
    /// [`Renderer::render`] does; [`FrameStats::loop_limited`]).
    pub loop_limited: u32,
}

/// An atlas's whole-frame marches, for the loop limiter's check: the compiled stack
/// and each tile's enabled instances and slice count (none with per-slice state or on
/// a GPU, where nothing is checked).
#[derive(Clone, Default)]
struct AtlasMarches {
    compiled: Option<Arc<CompiledStack>>,
    tiles: Vec<(Stack, u32)>,
}

/// A stack's enabled instances: (uid, plugin).
type Stack = Vec<(u64, Arc<dyn Plugin>)>;

impl std::fmt::Debug for AtlasMarches {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} tiles' marches checked", self.tiles.len())
    }
}

/// An atlas encoded into a caller's command encoder ([`Renderer::encode_atlas`]).
#[derive(Debug)]
pub struct EncodedAtlas {
    /// `cols·tile[0]` × `rows·tile[1]`, the eye buffer's format; COPY_SRC.
    pub texture: wgpu::Texture,
    pub cols: u32,
    pub rows: u32,
    pub tile: [u32; 2],
    pub prepasses_run: usize,
    pub volume_passes_run: usize,
    /// What [`Renderer::atlas_loop_limited`] checks.
    marches: AtlasMarches,
}

impl EncodedAtlas {
    /// The atlas size in pixels.
    pub fn size(&self) -> [u32; 2] {
        [self.cols * self.tile[0], self.rows * self.tile[1]]
    }
}

impl Atlas {
    /// The premultiplied pixels of tile `i`, row-major.
    pub fn tile_pixels(&self, i: usize) -> Vec<[f32; 4]> {
        let [tw, th] = self.tile.map(|v| v as usize);
        let width = tw * self.cols as usize;
        let (x0, y0) = ((i % self.cols as usize) * tw, (i / self.cols as usize) * th);
        (0..th)
            .flat_map(|y| {
                let start = (y0 + y) * width + x0;
                self.pixels[start..start + tw].iter().copied()
            })
            .collect()
    }
}

impl Renderer {
    /// Renders every tile into one atlas with one command encoder and one submission.
    /// `s` gives the tile size, slice spacing and early termination (its camera is each
    /// tile's); the backend must be compute. The tiles' stacks must share one
    /// structure: the same enabled plugins with the same structural values in the same
    /// order; their parameter values and instances differ. A stack with per-slice
    /// state (`shade.dos`) draws each tile's slices as its single render does, its
    /// state cleared per tile, in the same submission. Afterwards the renderer draws
    /// the first tile's stack. On a CPU device, an atlas whose loops ran out of
    /// llvmpipe's loop iterations ([`Renderer::atlas_loop_limited`]) is rendered again
    /// in smaller parts, as [`Renderer::render`] renders a frame again.
    pub fn render_atlas(
        &mut self,
        tiles: &[AtlasTile],
        s: &FrameSettings,
        target: TargetFormat,
        cols: u32,
    ) -> Result<Atlas, RenderError> {
        let start = Instant::now();
        let (mut prepasses_run, mut volume_passes_run) = (0, 0);
        loop {
            let mut enc = self
                .gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("vwb atlas"),
                });
            let encoded = self.encode_atlas(&mut enc, tiles, s, target, cols)?;
            self.gpu.queue.submit([enc.finish()]);
            prepasses_run += encoded.prepasses_run;
            volume_passes_run += encoded.volume_passes_run;
            let pixels = self.read_atlas(&encoded);
            let loop_limited = self.atlas_loop_limited(&encoded);
            if loop_limited > 0 && self.shrink_atlas_parts(&encoded) {
                continue;
            }
            if loop_limited > 0 {
                warn_loop_limited(loop_limited);
            }
            return Ok(Atlas {
                cols: encoded.cols,
                rows: encoded.rows,
                tile: encoded.tile,
                tiles: tiles.len(),
                pixels,
                wall_ms: start.elapsed().as_secs_f64() * 1e3,
                prepasses_run,
                volume_passes_run,
                loop_limited,
            });
        }
    }

    /// The invocations of an encoded atlas's marches that ran out of the device's loop
    /// iterations (llvmpipe's loop limiter, [`march_parts`]), so that their rays may be
    /// cut short: read after its encoder was submitted and before the renderer encodes
    /// again. 0 on a GPU and under per-slice state. A caller of
    /// [`Renderer::encode_atlas`] that finds some renders the atlas again after
    /// [`Renderer::shrink_atlas_parts`].
    pub fn atlas_loop_limited(&self, a: &EncodedAtlas) -> u32 {
        if a.marches.tiles.is_empty() {
            0
        } else {
            self.march.read(&self.gpu)
        }
    }

    /// After an atlas whose loops ran out ([`Renderer::atlas_loop_limited`]): marches
    /// each of its tiles' stacks in parts of at most a quarter of the longest it took,
    /// from now on, as [`Renderer::render`] does for a frame. Whether any shrank (not
    /// below one slice).
    pub fn shrink_atlas_parts(&mut self, a: &EncodedAtlas) -> bool {
        let Some(compiled) = a.marches.compiled.clone() else {
            return false;
        };
        // once per loop estimate (tiles of one estimate share their parts), by the
        // tile of most slices
        let mut by_estimate: std::collections::BTreeMap<u32, (&Stack, u32)> = Default::default();
        for (stack, count) in &a.marches.tiles {
            let estimate = self.loop_estimate(&compiled, stack);
            let most = by_estimate.entry(estimate).or_insert((stack, *count));
            if *count > most.1 {
                *most = (stack, *count);
            }
        }
        let mut any = false;
        for (stack, count) in by_estimate.into_values() {
            any |= self.shrink_parts_of(&compiled, stack, count);
        }
        any
    }

    /// Reads an encoded atlas back (after its encoder was submitted): premultiplied
    /// RGBA, row-major over the whole atlas.
    pub fn read_atlas(&self, a: &EncodedAtlas) -> Vec<[f32; 4]> {
        let bpp = a.texture.format().block_copy_size(None).unwrap_or(16);
        let bytes = read_texture(&self.gpu, &a.texture, bpp);
        let [w, h] = a.size();
        decode_rgba(&bytes, w, h, bpp)
    }

    /// Encodes the atlas of [`Renderer::render_atlas`] into the caller's command
    /// encoder (which may hold other work: several atlases or views per submission) and
    /// returns its texture (COPY_SRC). The caller submits the encoder before the
    /// renderer encodes or renders again: the pre-passes it encodes count as run.
    pub fn encode_atlas(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        tiles: &[AtlasTile],
        s: &FrameSettings,
        target: TargetFormat,
        cols: u32,
    ) -> Result<EncodedAtlas, RenderError> {
        if self.split.is_some() {
            return Err(RenderError::Atlas(
                "a volume split into bricks cannot be rendered into an atlas yet".into(),
            ));
        }
        if tiles.is_empty() || cols == 0 {
            return Err(RenderError::Atlas(
                "an atlas needs at least one tile and one column".into(),
            ));
        }
        if s.backend != Backend::Compute {
            return Err(RenderError::Atlas(
                "atlases render on the compute backend (--backend compute)".into(),
            ));
        }
        let rows = tiles.len().div_ceil(cols as usize) as u32;
        let (tw, th) = (s.width, s.height);
        let max = self.gpu.limits.max_texture_dimension_2d;
        if tw == 0 || th == 0 || cols.saturating_mul(tw) > max || rows.saturating_mul(th) > max {
            return Err(RenderError::BadSize(
                cols.saturating_mul(tw),
                rows.saturating_mul(th),
                max,
            ));
        }
        self.update_stack(tiles[0].stack, target)?;
        let p = self.pipelines.as_ref().expect("pipeline exists");
        // per-slice state: a stack with a plugin that declares it (the compiled
        // stack's updates are exactly those)
        let per_slice = !p.updates.is_empty();
        let structure: Vec<(&'static str, u64)> =
            p.key.entries.iter().map(|(_, id, h)| (*id, *h)).collect();
        let compiled = p.compiled.clone();

        // every tile's enabled instances, configured, with their GPU data
        let mut stacks: Vec<Vec<(u64, Arc<dyn Plugin>)>> = Vec::with_capacity(tiles.len());
        for (t, tile) in tiles.iter().enumerate() {
            let enabled: Vec<PluginInstance> = self
                .configure_stack(tile.stack)
                .into_iter()
                .filter(|i| i.enabled)
                .collect();
            let mine: Vec<(&'static str, u64)> = enabled
                .iter()
                .map(|i| (i.plugin.id(), structure_of(i)))
                .collect();
            if mine != structure {
                return Err(RenderError::Atlas(format!(
                    "tile {t}: its stack's structure differs from tile 0's (the plugins, their order and their structural parameters must be the same)"
                )));
            }
            for inst in &enabled {
                self.ensure_instance(inst)?;
                self.sync_params(inst)?;
            }
            stacks.push(enabled.iter().map(|i| (i.uid, i.plugin.clone())).collect());
        }
        // instances of an earlier atlas that this one does not use are dropped
        let live: std::collections::HashSet<u64> =
            stacks.iter().flatten().map(|(u, _)| *u).collect();
        let stale: Vec<u64> = self.atlas_uids.difference(&live).copied().collect();
        let main: std::collections::HashSet<u64> = self
            .pipelines
            .as_ref()
            .map(|p| p.uids().into_iter().collect())
            .unwrap_or_default();
        for uid in stale {
            if !main.contains(&uid) {
                self.instances.remove(&uid);
            }
        }
        self.atlas_uids = live;

        // the plans (one per camera) and spacing-dependent resources
        let views: Vec<_> = tiles
            .iter()
            .map(|t| t.camera.view(tw as f32 / th as f32))
            .collect();
        let plans = views
            .iter()
            .zip(&stacks)
            .map(|(v, stack)| self.frame_plan(stack, v, &self.vbox, s.slice_spacing))
            .collect::<Result<Vec<_>, _>>()?;
        if per_slice {
            let most = plans.iter().map(|p| p.slices.count).max().unwrap_or(0);
            if most > MAX_PER_SLICE_SLICES {
                return Err(RenderError::TooManyPerSliceSlices {
                    count: most,
                    max: MAX_PER_SLICE_SLICES,
                });
            }
            self.ensure_slice_info(most);
        }
        let spacing = plans[0].ray_spacing() / self.vbox.voxel;
        self.slice_spacing = spacing;
        for (uid, plugin) in stacks.iter().flatten() {
            if !plugin.uses_slice_spacing() {
                continue;
            }
            let Some(g) = self.instances.get(uid) else {
                continue;
            };
            if g.spacing != spacing {
                plugin.update_resources(&self.gpu_init(), &g.params, &g.resources)?;
                if let Some(g) = self.instances.get_mut(uid) {
                    g.spacing = spacing;
                }
            }
        }
        self.ensure_target(tw, th, target)?;
        if per_slice {
            // each tile's own state textures (the tiles of one variant share them,
            // cleared before each tile's slices)
            for stack in &stacks {
                self.ensure_state_of(stack);
            }
        }
        // pre-passes read the volume through the frame uniform
        self.write_frame(
            &FrameSettings {
                camera: tiles[0].camera,
                ..*s
            },
            &plans[0],
            &views[0],
        );

        // each tile's out-of-date volume passes (a variant's own light volume once per
        // variant; a view pass again for each tile whose camera differs from the one
        // its stack last ran with), planned in tile order before anything is encoded:
        // the plans may grow the slice-info buffer the passes index by step
        // (a stack without a view pass is planned once, at its first tile; one with a
        // view pass again at each tile, but its progressive passes refine at the first
        // only: one frame's refinement budget per variant, as a single render)
        let mut planned = std::collections::HashSet::new();
        let mut tile_plans: Vec<Vec<PassDispatch>> = Vec::with_capacity(stacks.len());
        for (stack, view) in stacks.iter().zip(&views) {
            let uids: Vec<u64> = stack.iter().map(|(u, _)| *u).collect();
            let viewed = stack
                .iter()
                .any(|(_, pl)| pl.volume_passes().iter().any(|d| d.camera));
            let first = planned.insert(uids);
            tile_plans.push(if compiled.volume_passes.is_empty() || !(first || viewed) {
                Vec::new()
            } else {
                self.plan_volume_passes(&compiled, stack, camera_key(view), first)
            });
        }
        let device = &self.gpu.device;
        let t = self.target.as_ref().expect("target exists");
        let atlas = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("vwb atlas"),
            size: wgpu::Extent3d {
                width: cols * tw,
                height: rows * th,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: target.wgpu(),
            usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let mut prepasses_run = 0;
        let mut done = Vec::new();
        for stack in &stacks {
            let dirty: Vec<usize> = self
                .dirty_prepasses(&compiled, stack)
                .into_iter()
                .filter(|i| !done.contains(&stack[*i].0))
                .collect();
            prepasses_run += self
                .encode_prepasses(enc, &compiled, stack, &dirty, &mut |_, _| {})
                .len();
            done.extend(dirty.iter().map(|i| stack[*i].0));
        }
        let mut volume_passes_run = 0;
        let whole = self
            .march
            .groups(device, &compiled.g3_layout, &t.view, &t.accum, &[[0, 0]]);
        // the loop limiter's counter over every tile's march (on a CPU device)
        let mut marches = AtlasMarches::default();
        if !per_slice && self.gpu.info.device_type == wgpu::DeviceType::Cpu {
            marches.compiled = Some(compiled.clone());
            self.march.clear(enc);
        }
        // group 2 holds per-slice state only: the same for every tile of a stack
        // without it; a stack with it binds each tile's own below
        let uids0: Vec<u64> = stacks[0].iter().map(|(u, _)| *u).collect();
        let [g2, _] = self.group2_for(&compiled, &uids0);
        // empty-space skipping by each tile's own classification, as its single render
        // would skip: one occupancy grid per distinct stack (the views of one variant
        // share it), made and uploaded once
        let mut occupancies = std::collections::HashMap::new();
        for (i, (stack, (view, plan))) in stacks.iter().zip(views.iter().zip(&plans)).enumerate() {
            let settings = FrameSettings {
                camera: tiles[i].camera,
                ..*s
            };
            let uids: Vec<u64> = stack.iter().map(|(u, _)| *u).collect();
            let occupancy = occupancies.entry(uids.clone()).or_insert_with(|| {
                self.occupancy_of(tiles[i].stack).map(|b| {
                    let buffer = upload_occupancy(&self.gpu, self.bricks.dims, &b);
                    let hull = self.hull_of(&b);
                    (b, buffer, hull)
                })
            });
            let occupancy_buffer = occupancy.as_ref().map(|(_, b, _)| b);
            // skipping (and the rays' visible box and hull) by this tile's own
            // classification
            let occupied = occupancy.as_ref().map(|(bytes, _, hull)| Occupied {
                bytes,
                hull: hull.as_ref().map(|(h, share)| (h, *share)),
            });
            let u = self.frame_uniform(&settings, plan, view, [tw, th], target, occupied);
            // with per-slice state, the tiles this tile's slices' dispatches cover
            let exit = per_slice
                .then(|| self.slice_exit_info(stack, plan, view, &u, [tw, th], occupied))
                .flatten();
            let frame = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vwb atlas frame"),
                contents: bytemuck::bytes_of(&u),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let g0 = self.g0_with(
                &frame,
                exit.as_ref()
                    .map_or([&self.slice_info, &self.no_tile_list], |x| {
                        [&x.info, &x.list]
                    }),
                occupancy_buffer.unwrap_or(&self.occupancy),
            );
            // this tile's passes, after the tiles before it were drawn: a view pass's
            // target then holds this tile's camera while the tile is drawn
            volume_passes_run += self
                .encode_volume_passes(enc, &compiled, stack, &tile_plans[i], &g0, &mut |_, _| {})
                .len();
            let g1 = self.group1_for(&compiled, &uids);
            if per_slice {
                self.encode_state_clear(enc, stack);
                self.encode_compute_slices(
                    enc,
                    &compiled,
                    &uids,
                    [&g0, &g1, &whole[0]],
                    &self.group2_for(&compiled, &uids),
                    plans[i].slices.count,
                    [tw, th],
                    plans[i].half.is_none(),
                    exit.as_ref(),
                );
            } else {
                // in parts as its single render would march (on a CPU device)
                let parts = self.march_parts(&compiled, stack, plans[i].slices.count);
                let g3s = self
                    .march
                    .groups(device, &compiled.g3_layout, &t.view, &t.accum, &parts);
                let pipeline = compiled.march_pipeline(occupancy_buffer.is_some());
                let [mx, my] = self.main_workgroup;
                let n = (tw.div_ceil(mx), th.div_ceil(my));
                super::encode_march(enc, pipeline, [&g0, &g1, &g2], &g3s, n);
                if marches.compiled.is_some() {
                    marches.tiles.push((stack.clone(), plans[i].slices.count));
                }
            }
            enc.copy_texture_to_texture(
                t.texture.as_image_copy(),
                wgpu::TexelCopyTextureInfo {
                    texture: &atlas,
                    mip_level: 0,
                    origin: wgpu::Origin3d {
                        x: (i as u32 % cols) * tw,
                        y: (i as u32 / cols) * th,
                        z: 0,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::Extent3d {
                    width: tw,
                    height: th,
                    depth_or_array_layers: 1,
                },
            );
        }
        if marches.compiled.is_some() {
            self.march.copy_out(enc);
        }
        self.mark_prepasses_done(done);
        self.counters.prepass_runs += prepasses_run as u64;
        self.counters.volume_pass_runs += volume_passes_run as u64;
        Ok(EncodedAtlas {
            texture: atlas,
            cols,
            rows,
            tile: [tw, th],
            prepasses_run,
            volume_passes_run,
            marches,
        })
    }
}
