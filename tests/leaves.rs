//! Leaf primitives (SPEC R1, R2, P3, P4; thesis 4.1–4.2, ch. 7): a tree with its own leaves,
//! camera-facing leaf billboards, leaves re-oriented away from their HLP centre ("children's
//! book") and elliptical "Van Gogh" leaves (reference image), and properties of each on small
//! synthetic plants with known geometry: billboards face the camera, re-oriented leaves turn
//! edge-on where they point sideways, ellipses are elongated around the HLP, leaf outlines add
//! ink, the abstract leaf shape covers more, HLP abstraction moves the particles, a far plant
//! draws fewer, larger particles, and photorealism brings back the original leaves.

mod common;

use common::{assert_matches_reference, full_detail, trees_on_a_plain};
use glam::Vec3;
use landsketch::render::style::LeafMode;
use landsketch::render::{FrameRequest, Readback, Renderer, Style};
use landsketch::scene::Species;
use landsketch::scene::camera::Camera;
use landsketch::scene::mesh::Mesh;
use landsketch::scene::plant::{Material, MeshPart, PartKind, PlantModel};
use std::path::Path;

const MODES: [LeafMode; 4] = [LeafMode::Original, LeafMode::Billboard, LeafMode::Reoriented, LeafMode::Elliptical];
const WIDTH: u32 = 200;
const HEIGHT: u32 = 240;

/// Looking north at the tree at the origin from `distance` metres, aimed at its crown.
fn camera_at(distance: f32) -> Camera {
    let pitch = (4.0f32 / distance).atan().to_degrees();
    Camera::perspective([0.0, -distance, 101.7], 0.0, pitch, 45.0)
}

/// Pen and ink over light colour, so leaves show as shapes and as strokes.
fn sketch(mode: LeafMode) -> Style {
    Style { leaf_mode: mode, color: 0.5, color_abstraction: 0.3, hlp_abstraction: 0.3, ..Style::default() }
}

/// Colour with outlined leaves and no hatching: the leaves' shapes.
fn outlined(mode: LeafMode) -> Style {
    Style { leaf_mode: mode, color: 1.0, hatch_strength: 0.0, leaf_outline: 0.1, normal_blend: 0.3, ..Style::default() }
}

/// The object IDs of the image show a plant.
fn plant_mask(renderer: &Renderer, camera: &Camera, style: &Style) -> Vec<bool> {
    let ids = renderer
        .render(FrameRequest::new(camera, style, WIDTH, HEIGHT).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    ids.iter().map(|id| id >> 24 >= 2).collect()
}

fn count(mask: &[bool]) -> usize {
    mask.iter().filter(|p| **p).count()
}

/// Width / height of the bounding box of the plant pixels.
fn aspect(mask: &[bool]) -> f32 {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (i, _) in mask.iter().enumerate().filter(|(_, p)| **p) {
        let (x, y) = (i as u32 % WIDTH, i as u32 / WIDTH);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    (x1 + 1 - x0) as f32 / (y1 + 1 - y0) as f32
}

/// An untextured leaf card of half size `half` at `center` with normal `normal` (its u axis
/// horizontal, or along x for a horizontal card).
fn card(mesh: &mut Mesh, center: Vec3, normal: Vec3, half: f32) {
    let u = Vec3::Z.cross(normal).try_normalize().unwrap_or(Vec3::X) * half;
    mesh.push_card(center, u, normal.cross(u));
}

/// A renderer at full detail for one plant of `mesh` (foliage only) at the origin of the
/// plain, all its leaves in one HLP.
fn single_plant(mesh: Mesh) -> Renderer {
    let material = Material {
        name: "leaves".into(),
        base_color: [0.3, 0.6, 0.2, 1.0],
        texture: None,
        alpha_cutoff: Some(0.5),
        double_sided: true,
    };
    let model = PlantModel { name: "cards".into(), parts: vec![MeshPart { kind: PartKind::Foliage, mesh, material }] };
    let mut scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let mut species = Species::new("cards", model);
    species.hlp_radius = 5.0;
    scene.species[0] = species;
    full_detail(&scene)
}

fn mode(leaf_mode: LeafMode) -> Style {
    Style { leaf_mode, ..Style::default() }
}

#[test]
fn every_leaf_mode_matches_its_reference() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = camera_at(12.0);
    let mut sheet = image::RgbaImage::new(WIDTH * 4, HEIGHT * 2);
    let mut images = Vec::new();
    for (col, leaf_mode) in MODES.into_iter().enumerate() {
        for (row, style) in [sketch(leaf_mode), outlined(leaf_mode)].into_iter().enumerate() {
            let image = renderer.render(FrameRequest::new(&camera, &style, WIDTH, HEIGHT)).map(|f| f.image).unwrap();
            image::imageops::replace(&mut sheet, &image, i64::from(WIDTH) * col as i64, i64::from(HEIGHT) * row as i64);
            images.push(image);
        }
        let plant = count(&plant_mask(&renderer, &camera, &sketch(leaf_mode)));
        assert!(plant > 8000, "{leaf_mode:?}: the tree covers only {plant} pixels");
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/leaf_modes.png"), 0.03);
    // At this size a particle mode draws a quarter of the 1200 leaves, a quad each.
    let triangles = |leaf_mode| {
        renderer.draw_stats(&FrameRequest::new(&camera, sketch(leaf_mode), WIDTH, HEIGHT)).expect("stats").triangles
    };
    assert_eq!(triangles(LeafMode::Original) - triangles(LeafMode::Elliptical), 2 * (1200 - 300));
    for (i, image) in images.iter().enumerate().skip(2) {
        assert_ne!(image, &images[i % 2], "{:?} draws the original leaves", MODES[i / 2]);
    }
}

#[test]
fn billboards_face_the_camera_from_every_side() {
    // One 1 m × 1 m card facing south, seen face-on from the south and edge-on from the east.
    let mut mesh = Mesh::default();
    card(&mut mesh, Vec3::new(0.0, 0.0, 1.0), Vec3::NEG_Y, 0.5);
    let renderer = single_plant(mesh);
    let south = Camera::perspective([0.0, -6.0, 101.0], 0.0, 0.0, 45.0);
    let east = Camera::perspective([6.0, 0.0, 101.0], 270.0, 0.0, 45.0);
    let face_on = count(&plant_mask(&renderer, &south, &mode(LeafMode::Original)));
    // The card's projection: 1 m at 6 m with 240 px per 2·tan(22.5°) of view: ~48 px square.
    assert!((1800..2800).contains(&face_on), "{face_on}");
    assert!(count(&plant_mask(&renderer, &east, &mode(LeafMode::Original))) < face_on / 20, "edge-on card");
    for camera in [south, east] {
        let billboard = count(&plant_mask(&renderer, &camera, &mode(LeafMode::Billboard)));
        assert!(billboard.abs_diff(face_on) * 10 < face_on, "billboard covers {billboard}, the card face-on {face_on}");
        // `leaf_size` scales the particle: twice the size, four times the pixels.
        let twice = count(&plant_mask(&renderer, &camera, &Style { leaf_size: 2.0, ..mode(LeafMode::Billboard) }));
        assert!((3.5..4.5).contains(&(twice as f32 / billboard as f32)), "{twice} vs {billboard}");
    }
}

#[test]
fn reoriented_leaves_point_away_from_their_hlp_centre() {
    // Twelve horizontal cards on a circle of 1.5 m around one HLP, seen from above: face-on as
    // modelled, edge-on once each turns its normal away from the centre (N_HLP, eq. 4.7), and
    // face-on again as billboards.
    let mut mesh = Mesh::default();
    for k in 0..12 {
        let a = k as f32 * std::f32::consts::TAU / 12.0;
        card(&mut mesh, Vec3::new(1.5 * a.cos(), 1.5 * a.sin(), 1.0), Vec3::Z, 0.3);
    }
    let renderer = single_plant(mesh);
    let above = Camera::plan(0.0, 0.0, 120.0, 5.0);
    let original = count(&plant_mask(&renderer, &above, &mode(LeafMode::Original)));
    let reoriented = count(&plant_mask(&renderer, &above, &mode(LeafMode::Reoriented)));
    let billboard = count(&plant_mask(&renderer, &above, &mode(LeafMode::Billboard)));
    assert!(original > 2000, "{original}");
    assert!(reoriented * 10 < original, "re-oriented {reoriented} vs original {original}");
    assert!(billboard.abs_diff(original) * 10 < original, "billboards {billboard} vs original {original}");
}

#[test]
fn elliptical_leaves_are_elongated_around_the_hlp() {
    // Two cards facing south in one HLP, one in front of the other: seen from the south the
    // front one hides the back one. As an ellipse tangent to the HLP sphere it is 2.5 times as
    // wide (around the HLP's vertical axis) as it is high; as modelled, square.
    let mut mesh = Mesh::default();
    card(&mut mesh, Vec3::new(0.0, -1.0, 1.0), Vec3::NEG_Y, 0.5);
    card(&mut mesh, Vec3::new(0.0, 1.0, 1.0), Vec3::NEG_Y, 0.5);
    let renderer = single_plant(mesh);
    let south = Camera::perspective([0.0, -6.0, 101.0], 0.0, 0.0, 45.0);
    let square = aspect(&plant_mask(&renderer, &south, &mode(LeafMode::Original)));
    assert!((0.9..1.1).contains(&square), "{square}");
    let elliptical = plant_mask(&renderer, &south, &mode(LeafMode::Elliptical));
    let ratio = aspect(&elliptical);
    assert!((2.2..2.8).contains(&ratio), "{ratio}");
    // The ellipse keeps the card's area (an untextured card covers all of it): π·a·b = 1 m².
    let card_pixels = count(&plant_mask(&renderer, &south, &mode(LeafMode::Original)));
    let ellipse_pixels = count(&elliptical);
    assert!(ellipse_pixels.abs_diff(card_pixels) * 6 < card_pixels, "{ellipse_pixels} vs {card_pixels}");
}

#[test]
fn outlines_add_ink_and_abstract_shapes_cover_more() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = camera_at(12.0);
    // Colour only, red ink: the only ink is the leaf outline of thesis eq. 4.1.
    let base = Style {
        color: 1.0,
        hatch_strength: 0.0,
        contour_strength: 0.0,
        silhouette_strength: 0.0,
        ink: [1.0, 0.0, 0.0],
        ..Style::default()
    };
    let red = |style: &Style| {
        let image = renderer.render(FrameRequest::new(&camera, style, WIDTH, HEIGHT)).map(|f| f.image).unwrap();
        image.pixels().filter(|p| p[0] > 200 && p[1] < 80 && p[2] < 80).count()
    };
    for leaf_mode in MODES {
        let none = red(&Style { leaf_mode, ..base.clone() });
        let thin = red(&Style { leaf_mode, leaf_outline: 0.05, ..base.clone() });
        let thick = red(&Style { leaf_mode, leaf_outline: 0.2, ..base.clone() });
        assert_eq!(none, 0, "{leaf_mode:?}");
        assert!(thin > 100 && thick > thin, "{leaf_mode:?}: outline pixels {thin} (0.05), {thick} (0.2)");
    }
    // Thesis 4.1: α_t from α_max to α_min selects larger, more abstract leaf shapes.
    for leaf_mode in [LeafMode::Original, LeafMode::Billboard] {
        let original = count(&plant_mask(&renderer, &camera, &Style { leaf_mode, ..base.clone() }));
        let abstract_ = count(&plant_mask(&renderer, &camera, &Style { leaf_mode, leaf_shape: 1.0, ..base.clone() }));
        assert!(abstract_ as f32 > 1.05 * original as f32, "{leaf_mode:?}: {abstract_} vs {original}");
    }
}

#[test]
fn hlp_abstraction_moves_the_particles() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = camera_at(12.0);
    for leaf_mode in [LeafMode::Billboard, LeafMode::Elliptical] {
        let loose = plant_mask(&renderer, &camera, &mode(leaf_mode));
        let round = plant_mask(&renderer, &camera, &Style { hlp_abstraction: 1.0, ..mode(leaf_mode) });
        let both = loose.iter().zip(&round).filter(|(a, b)| **a && **b).count();
        let either = loose.iter().zip(&round).filter(|(a, b)| **a || **b).count();
        assert!((both as f32) < 0.9 * either as f32, "{leaf_mode:?}: overlap {both} of {either}");
    }
}

#[test]
fn a_far_plant_draws_fewer_larger_particles() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let leaves = scene.species[0].model.triangle_count_of(PartKind::Foliage) as u64 / 2;
    assert_eq!(leaves, 1200);
    let (near, far) = (camera_at(10.0), camera_at(60.0));
    let stats = |camera: &Camera, leaf_mode| {
        renderer.draw_stats(&FrameRequest::new(camera, mode(leaf_mode), 400, 480)).expect("stats")
    };
    // As modelled, every card at every distance: the source geometry.
    let original = stats(&near, LeafMode::Original).triangles;
    assert_eq!(stats(&far, LeafMode::Original).triangles, original);
    for leaf_mode in [LeafMode::Billboard, LeafMode::Reoriented, LeafMode::Elliptical] {
        // Near: all 1200 leaves, a quad each, as many triangles as the model's cards. Far: a
        // quarter of them (300, the fewest share that keeps 200 particles).
        assert_eq!(stats(&near, leaf_mode).triangles, original, "{leaf_mode:?}");
        assert_eq!(stats(&far, leaf_mode).triangles, original - 2 * (leaves - leaves / 4), "{leaf_mode:?}");
    }
    // The fewer particles are twice as large: the crown covers about as much as with all.
    let far_mask = |style: &Style| {
        let ids = renderer
            .render(FrameRequest::new(&far, style, 400, 480).read(Readback::IDS))
            .map(|f| f.ids.unwrap_or_default())
            .unwrap();
        ids.iter().filter(|id| *id >> 24 >= 2).count() as f32
    };
    let ratio = far_mask(&mode(LeafMode::Billboard)) / far_mask(&mode(LeafMode::Original));
    assert!((0.7..1.5).contains(&ratio), "{ratio}");
}

#[test]
fn photorealism_draws_the_original_leaves() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = camera_at(12.0);
    let photo = Style { photorealism: 1.0, ..Style::default() };
    let leaves =
        Style { leaf_mode: LeafMode::Elliptical, leaf_size: 2.0, leaf_shape: 1.0, leaf_outline: 0.3, ..photo.clone() };
    assert_eq!(
        renderer.render(FrameRequest::new(&camera, &leaves, WIDTH, HEIGHT)).map(|f| f.image).unwrap(),
        renderer.render(FrameRequest::new(&camera, &photo, WIDTH, HEIGHT)).map(|f| f.image).unwrap()
    );
}

/// Distance-dependent abstraction (thesis 7.3, "increased abstraction of the background"): a
/// tree nearer than `abstraction_near` is drawn as without it, one beyond `abstraction_far` as
/// with HLP abstraction and normal blend at 1 — the same pixels — and the two differ.
#[test]
fn abstraction_rises_with_distance() {
    let rising = Style {
        leaf_mode: LeafMode::Elliptical,
        distance_abstraction: 1.0,
        abstraction_near: 40.0,
        abstraction_far: 60.0,
        ..Style::default()
    };
    let plain = Style { distance_abstraction: 0.0, ..rising.clone() };
    let full = Style { hlp_abstraction: 1.0, normal_blend: 1.0, ..plain.clone() };
    for (distance, same, other, name) in [(20.0f32, &plain, &full, "none"), (90.0, &full, &plain, "full")] {
        let scene = trees_on_a_plain(&[[0.0, 0.0]]);
        let renderer = full_detail(&scene);
        let camera = camera_at(distance);
        let render = |style: &Style| {
            renderer.render(FrameRequest::new(&camera, style, WIDTH, HEIGHT)).map(|f| f.image).expect("render")
        };
        let image = render(&rising);
        image.save(std::env::temp_dir().join(format!("landsketch-distance-abstraction-{distance}.png"))).ok();
        assert!(image == render(same), "the tree {distance} m away is drawn with {name} abstraction");
        let changed = image.pixels().zip(render(other).pixels()).filter(|(a, b)| a != b).count();
        assert!(changed > 50, "the abstraction shows on the tree {distance} m away ({changed} pixels)");
    }
}

/// Stroke simplification with distance (thesis 7.3): a tree nearer than `abstraction_near` is
/// hatched as without it; one beyond `abstraction_far` loses the lifted share of its strokes —
/// all of them at 1, as `hatch_brightness` 1 draws it — and fewer at a half.
#[test]
fn strokes_simplify_with_distance() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let simplified = |share: f32| Style {
        distance_simplification: share,
        abstraction_near: 40.0,
        abstraction_far: 60.0,
        contour_strength: 0.0,
        silhouette_strength: 0.0,
        ..Style::default()
    };
    for distance in [20.0f32, 90.0] {
        let camera = camera_at(distance);
        // The tree's pixels (the plain behind the near tree lies beyond `abstraction_near`).
        let tree = plant_mask(&renderer, &camera, &simplified(0.0));
        let render = |style: &Style| -> Vec<image::Rgba<u8>> {
            let image = renderer.render(FrameRequest::new(&camera, style, WIDTH, HEIGHT)).map(|f| f.image).unwrap();
            image.pixels().zip(&tree).filter(|(_, t)| **t).map(|(p, _)| *p).collect()
        };
        let ink = |pixels: &[image::Rgba<u8>]| pixels.iter().filter(|p| common::luminance(p) < 0.5).count();
        let (none, half, all) = (render(&simplified(0.0)), render(&simplified(0.5)), render(&simplified(1.0)));
        if distance < 40.0 {
            assert!(none == half && none == all, "the tree {distance} m away keeps its strokes");
            continue;
        }
        let blank = render(&Style { hatch_brightness: 1.0, ..simplified(0.0) });
        assert!(all == blank, "at 1 the far tree keeps no strokes");
        let (none, half, all) = (ink(&none), ink(&half), ink(&all));
        assert!(none > half && half > all, "ink falls as the strokes simplify: {none} > {half} > {all}");
    }
}

/// The shapes (`leaf_mode` `shapes`) and the styles they are shown in: a sketch, and the
/// `toon_shapes` preset's colour with its 3-band ramp.
fn shape_styles() -> [Style; 2] {
    let toon = landsketch::render::presets::preset("toon_shapes").expect("the toon_shapes preset");
    [Style { leaf_mode: LeafMode::Shapes, ..sketch(LeafMode::Shapes) }, toon]
}

#[test]
fn substitution_shapes_stand_for_the_branch_clusters_at_both_finer_levels() {
    use landsketch::prep::hlp;
    use landsketch::prep::lod::{LodLevel, LodSettings};
    use landsketch::render::RenderOptions;
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let species = &scene.species[0];
    let hlps = hlp::cluster(&species.model, species.hlp_radius).spheres.len();
    let forced = |level| {
        let lod = LodSettings { force: Some(level), ..LodSettings::default() };
        Renderer::with_options(common::gpu(), &scene, &RenderOptions { lod, ..RenderOptions::default() })
            .expect("renderer")
    };
    let (full, hlp_level) = (forced(LodLevel::Full), forced(LodLevel::Hlp));
    let camera = camera_at(12.0);
    let [sketched, toon] = shape_styles();
    // The G-buffer's surface kinds and patches of the plant's pixels: every foliage pixel is a
    // shape (surface 2, foliage), one patch per HLP, at the full level and at the HLP level,
    // which draws no billboard (surface 3).
    let patches = |renderer: &Renderer, style: &Style| {
        let frame = renderer.render(FrameRequest::new(&camera, style, WIDTH, HEIGHT).read(Readback::IDS)).unwrap();
        let (ids, second) = (frame.ids.unwrap_or_default(), frame.patches.unwrap_or_default());
        let mut surfaces = std::collections::BTreeSet::new();
        let mut patches = std::collections::BTreeSet::new();
        for (_, &patch) in ids.iter().zip(&second).filter(|(id, _)| **id >> 24 >= 2) {
            surfaces.insert(patch >> 24);
            if patch & 0x00FF_FFFF != 0 {
                patches.insert(patch & 0x00FF_FFFF);
            }
        }
        (surfaces, patches.len())
    };
    for (name, renderer) in [("full", &full), ("HLP", &hlp_level)] {
        let (surfaces, count) = patches(renderer, &sketched);
        assert!(!surfaces.contains(&3), "{name} level: billboards drawn with shapes: {surfaces:?}");
        assert!(surfaces.contains(&2), "{name} level: no shape drawn: {surfaces:?}");
        assert!(count * 2 >= hlps && count <= hlps, "{name} level: {count} shapes seen of {hlps} HLPs");
    }
    // The shapes are the model's size: the tree covers about what its leaves cover.
    let leaves = count(&plant_mask(&full, &camera, &sketch(LeafMode::Original)));
    let shapes = count(&plant_mask(&full, &camera, &sketched));
    assert!(shapes as f32 > 0.6 * leaves as f32 && (shapes as f32) < 1.6 * leaves as f32, "{shapes} against {leaves}");
    // Toon shading (Campos et al. §4, a 1D ramp of 3 bands): apart from outlines and the
    // dark gaps between shapes, the crown's pixels take a few colours.
    let image = full.render(FrameRequest::new(&camera, &toon, WIDTH, HEIGHT)).map(|f| f.image).unwrap();
    let mask = plant_mask(&full, &camera, &toon);
    let mut colours = std::collections::HashMap::new();
    for (pixel, _) in image.pixels().zip(&mask).filter(|(p, m)| **m && common::luminance(p) > 0.2) {
        *colours.entry([pixel[0] / 8, pixel[1] / 8, pixel[2] / 8]).or_insert(0usize) += 1;
    }
    let mut counts: Vec<usize> = colours.values().copied().collect();
    counts.sort_unstable_by(|a, b| b.cmp(a));
    let lit: usize = counts.iter().sum();
    assert!(
        counts.iter().take(4).sum::<usize>() * 10 >= lit * 8,
        "more than a few tones: {:?}",
        &counts[..10.min(counts.len())]
    );
    let mut sheet = image::RgbaImage::new(WIDTH * 3, HEIGHT);
    for (col, (renderer, style)) in
        [(&full, &sketched), (&hlp_level, &sketched), (&full, &toon)].into_iter().enumerate()
    {
        let image = renderer.render(FrameRequest::new(&camera, style, WIDTH, HEIGHT)).map(|f| f.image).unwrap();
        image::imageops::replace(&mut sheet, &image, i64::from(WIDTH) * col as i64, 0);
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/substitution_shapes.png"), 0.03);
}
