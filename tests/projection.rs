//! D2–D5 render tests in plan view: data layers projected onto a flat plain (lit from the
//! zenith, so the bare sketch is paper) and seen from above. A label checkerboard shows its
//! palette colour in each square, a scalar ramp runs monotonically through the colour map, a
//! two-step series at its midpoint time shows the midpoint colour, nodata cells stay paper,
//! the other Table 9.1 features (hatch tone, hatch pattern, silhouettes) change the ink, and
//! hatch colours (thesis 9.2.2, Fig. 9.3) draw one coloured hatching per field.
//! References in `tests/reference/projection/`.

mod common;

use chrono::{DateTime, Utc};
use common::{assert_matches_reference, fraction, gpu, luminance, trees_on_a_plain};
use landsketch::fields::{
    ColorMapName, ColorMapSpec, Field, FieldKind, FieldStep, Lut, Mapping, MappingTarget, parse_time,
};
use landsketch::gis::{Crs, CrsDefinition, GeoTransform, Raster};
use landsketch::render::projection::{DataLayer, DataMapping, DataView};
use landsketch::render::{FrameRequest, RenderError, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use std::path::Path;
use std::sync::{Arc, OnceLock};

const SIZE: u32 = 128;
/// Scene metres across the plan view: the field squares below are 50 m, 32 px.
const VIEW_WIDTH: f32 = 200.0;
/// The plain's scene origin in UTM 13N (its DEM spans 500000…500210 E, 4399790…4400000 N).
const ORIGIN: (f64, f64) = (500_105.0, 4_399_895.0);

fn plain() -> &'static (Scene, Renderer) {
    static PLAIN: OnceLock<(Scene, Renderer)> = OnceLock::new();
    PLAIN.get_or_init(|| {
        let scene = trees_on_a_plain(&[]);
        let renderer = Renderer::new(gpu(), &scene).expect("renderer");
        (scene, renderer)
    })
}

/// A plan view of the plain, north up.
fn plan() -> Camera {
    Camera::plan(0.0, 0.0, 300.0, VIEW_WIDTH)
}

/// No hatching or contours, so data colours show on paper alone.
fn plain_style() -> Style {
    Style { hatch_strength: 0.0, contour_strength: 0.0, silhouette_strength: 0.0, ..Style::default() }
}

/// One time step of a test field: its time ("" for none) and the value of each cell.
type Step<'a> = (&'a str, &'a dyn Fn(usize, usize) -> f64);

/// A `cols × rows` field in UTM 13N with `cell`-metre cells whose north-west corner is at
/// scene (−100, 100); `value(col, row)` gives the cells (NaN: nodata).
fn field(kind: FieldKind, cols: usize, rows: usize, cell: f64, steps: &[Step<'_>]) -> Field {
    let steps = steps
        .iter()
        .map(|(time, value)| FieldStep {
            time: (!time.is_empty()).then(|| parse_time(time).expect("time")),
            raster: Raster {
                width: cols,
                height: rows,
                data: (0..rows).flat_map(|r| (0..cols).map(move |c| value(c, r))).collect(),
                nodata: None,
                transform: GeoTransform {
                    origin_x: ORIGIN.0 - 100.0,
                    origin_y: ORIGIN.1 + 100.0,
                    cell_width: cell,
                    cell_height: cell,
                },
                crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
                palette: None,
            },
        })
        .collect();
    Field::new(kind, CrsDefinition::from_epsg(32613).expect("UTM 13N"), None, steps).expect("field")
}

fn view(key: &str, field: Field, mapping: Mapping, time: Option<DateTime<Utc>>) -> DataView {
    let layer = Arc::new(DataLayer { key: key.into(), field });
    DataView { mappings: vec![DataMapping { layer, mapping }], time }
}

fn render(data: &DataView, style: &Style) -> image::RgbaImage {
    plain().1.render(FrameRequest::new(&plan(), style, SIZE, SIZE).data(data)).map(|f| f.image).expect("render")
}

/// The pixel at scene point (x, y) of the plan view.
fn pixel_at(image: &image::RgbaImage, x: f32, y: f32) -> [u8; 3] {
    let scale = SIZE as f32 / VIEW_WIDTH;
    let (px, py) = ((x * scale + SIZE as f32 / 2.0) as u32, (SIZE as f32 / 2.0 - y * scale) as u32);
    let p = image.get_pixel(px.min(SIZE - 1), py.min(SIZE - 1));
    [p[0], p[1], p[2]]
}

/// A table colour as it shows on paper (the sketch is multiplied by the colour).
fn on_paper(c: [u8; 4]) -> [u8; 3] {
    let paper = Style::default().paper;
    std::array::from_fn(|i| (f32::from(c[i]) * paper[i]).round() as u8)
}

fn assert_close(actual: [u8; 3], expected: [u8; 3], what: &str) {
    let worst = (0..3).map(|i| actual[i].abs_diff(expected[i])).max().unwrap_or(0);
    assert!(worst <= 4, "{what}: {actual:?} instead of {expected:?}");
}

fn reference(name: &str) -> std::path::PathBuf {
    Path::new("tests/reference/projection").join(format!("{name}.png"))
}

/// Centre of checkerboard square (`col`, `row`) of 50 m squares from (−100, 100).
fn square_center(col: usize, row: usize) -> (f32, f32) {
    (-75.0 + 50.0 * col as f32, 75.0 - 50.0 * row as f32)
}

#[test]
fn label_checkerboard_shows_each_palette_colour() {
    let board = field(FieldKind::Label, 4, 4, 50.0, &[("", &|c, r| 1.0 + ((c + r) % 2) as f64 * 4.0)]);
    let lut = Lut::for_field(&ColorMapSpec::default(), &board).unwrap();
    let image = render(&view("board", board, Mapping::new("board", MappingTarget::Color), None), &plain_style());
    assert_matches_reference(&image, &reference("checkerboard"), 0.02);
    for row in 0..4 {
        for col in 0..4 {
            let (x, y) = square_center(col, row);
            let class = (col + row) % 2;
            assert_close(pixel_at(&image, x, y), on_paper(lut.colors[class]), &format!("square {col},{row}"));
        }
    }
    // Tableau 10: blue for the first class, orange for the second.
    assert!(pixel_at(&image, -75.0, 75.0)[2] > 150 && pixel_at(&image, -25.0, 75.0)[0] > 200);
}

#[test]
fn scalar_ramp_runs_monotonically_through_the_colour_map() {
    // Values grow eastwards: 0 … 15 over 16 columns of 12.5 m.
    let ramp = field(FieldKind::Scalar, 16, 16, 12.5, &[("", &|c, _| c as f64)]);
    let mapping = Mapping { colormap: Some(ColorMapName::Magma), ..Mapping::new("ramp", MappingTarget::Color) };
    let lut = Lut::for_field(&mapping.color_spec(0), &ramp).unwrap();
    let image = render(&view("ramp", ramp, mapping, None), &plain_style());
    assert_matches_reference(&image, &reference("ramp"), 0.02);
    // Along the ramp, each pixel's nearest table entry must not go back.
    let mut last = 0;
    let mut entries = Vec::new();
    for i in 0..=24 {
        let x = -93.75 + 187.5 * i as f32 / 24.0;
        let actual = pixel_at(&image, x, 0.0);
        let nearest = (0..lut.colors.len())
            .min_by_key(|&k| {
                let c = on_paper(lut.colors[k]);
                (0..3).map(|j| i32::from(c[j]).abs_diff(i32::from(actual[j]))).sum::<u32>()
            })
            .unwrap();
        assert!(nearest + 3 >= last, "x {x}: entry {nearest} after {last}");
        last = last.max(nearest);
        entries.push(nearest);
    }
    assert!(entries[0] < 10 && entries[24] > 245, "{entries:?}");
    // Between cell centres the value is bilinear: the midpoint of cells 7 and 8 is 7.5.
    assert_close(pixel_at(&image, 0.0, 0.0), on_paper(lut.color_of(7.5)), "ramp midpoint");
}

#[test]
fn two_step_series_at_the_midpoint_shows_the_midpoint_colour() {
    let series = || field(FieldKind::Scalar, 4, 4, 50.0, &[("2000-01-01", &|_, _| 0.0), ("2000-01-11", &|_, _| 10.0)]);
    let lut = Lut::for_field(&ColorMapSpec::default(), &series()).unwrap();
    let at = |t: &str| {
        let time = Some(parse_time(t).unwrap());
        render(&view("series", series(), Mapping::new("series", MappingTarget::Color), time), &plain_style())
    };
    let mid = at("2000-01-06");
    assert_matches_reference(&mid, &reference("series_midpoint"), 0.02);
    // Eq. 9.4: u = 0.5 → value 5 → table entry round(0.5 · 255) = 128.
    assert_close(pixel_at(&mid, 10.0, -20.0), on_paper(lut.colors[128]), "midpoint");
    assert_close(pixel_at(&at("2000-01-03T12:00:00Z"), 10.0, -20.0), on_paper(lut.color_of(2.5)), "a quarter");
    // Outside the series: clamped to the first and last steps.
    assert_close(pixel_at(&at("1990-01-01"), 10.0, -20.0), on_paper(lut.colors[0]), "before");
    assert_close(pixel_at(&at("2030-01-01"), 10.0, -20.0), on_paper(lut.colors[255]), "after");
}

#[test]
fn nodata_cells_show_the_no_data_colour() {
    // The north-west quarter (2 × 2 squares) holds no data; elsewhere the values grow east.
    let holes = field(FieldKind::Scalar, 4, 4, 50.0, &[("", &|c, r| if c < 2 && r < 2 { f64::NAN } else { c as f64 })]);
    let lut = Lut::for_field(&ColorMapSpec::default(), &holes).unwrap();
    let image = render(&view("holes", holes, Mapping::new("holes", MappingTarget::Color), None), &plain_style());
    assert_matches_reference(&image, &reference("nodata"), 0.02);
    let paper = on_paper([255; 4]);
    for (col, row) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (x, y) = square_center(col, row);
        assert_close(pixel_at(&image, x, y), paper, &format!("nodata square {col},{row}"));
    }
    // D1: bilinear sampling is nodata wherever a nodata cell has weight, so the data square
    // next to the hole is paper up to its own cell centre and coloured beyond it.
    let (x, y) = square_center(0, 2);
    assert_close(pixel_at(&image, x, y + 10.0), paper, "within half a cell of the hole");
    assert_close(pixel_at(&image, x, y - 10.0), on_paper(lut.color_of(0.0)), "beyond the cell centre");
    let (x, y) = square_center(3, 3);
    assert_close(pixel_at(&image, x, y), on_paper(lut.color_of(3.0)), "far from the hole");
}

#[test]
fn hatch_tone_and_pattern_follow_the_labels() {
    // West half label 0, east half label 1.
    let halves = Arc::new(DataLayer {
        key: "halves".into(),
        field: field(FieldKind::Label, 2, 2, 100.0, &[("", &|c, _| c as f64)]),
    });
    let style = Style { contour_strength: 0.0, silhouette_strength: 0.0, ..Style::default() };
    let ink = |image: &image::RgbaImage, east: bool| {
        let half = image::imageops::crop_imm(image, if east { SIZE / 2 + 4 } else { 4 }, 30, SIZE / 2 - 8, SIZE - 60);
        fraction(&half.to_image(), |l| l < 0.5)
    };
    let on = |layer: &Arc<DataLayer>, mapping: Mapping| DataMapping { layer: layer.clone(), mapping };
    let tone_of_halves = on(&halves, Mapping::new("halves", MappingTarget::HatchTone));
    let tone = render(&DataView { mappings: vec![tone_of_halves], time: None }, &style);
    assert_matches_reference(&tone, &reference("hatch_tone"), 0.03);
    let (west, east) = (ink(&tone, false), ink(&tone, true));
    assert!(west < 0.01 && east > 0.3, "label 0 bare ({west}), label 1 hatched darkly ({east})");
    // D4, two fields: a constant field sets a middle tone everywhere; the labels pick the
    // hatch pattern: TAM 0 (the style's lines) for label 0, TAM 1 (cross-hatching) for label 1.
    let constant = Arc::new(DataLayer {
        key: "constant".into(),
        field: field(FieldKind::Scalar, 1, 1, 200.0, &[("", &|_, _| 1.0)]),
    });
    let middle =
        on(&constant, Mapping { range: Some([0.0, 2.0]), ..Mapping::new("constant", MappingTarget::HatchTone) });
    let pattern = on(&halves, Mapping::new("halves", MappingTarget::HatchPattern));
    let toned = render(&DataView { mappings: vec![middle.clone()], time: None }, &style);
    let patterned = render(&DataView { mappings: vec![middle, pattern], time: None }, &style);
    assert_matches_reference(&patterned, &reference("hatch_pattern"), 0.03);
    assert!(ink(&toned, false) > 0.05 && ink(&toned, true) > 0.05, "the middle tone is hatched");
    let differs = |east: bool| {
        let x0 = if east { SIZE / 2 + 4 } else { 4 };
        (x0..x0 + SIZE / 2 - 8)
            .flat_map(|x| (30..SIZE - 30).map(move |y| (x, y)))
            .filter(|&(x, y)| patterned.get_pixel(x, y) != toned.get_pixel(x, y))
            .count()
    };
    assert_eq!(differs(false), 0, "label 0 keeps the style's TAM");
    assert!(differs(true) > 200, "label 1 switches to another TAM");
}

/// Whether a pixel is ink of `rgb` (an sRGB colour with one dominant channel): its dominant
/// channel exceeds both others by 40 levels.
fn is_ink_of(p: [u8; 3], rgb: [f32; 3]) -> bool {
    let dominant = (0..3).max_by(|&a, &b| rgb[a].total_cmp(&rgb[b])).unwrap_or(0);
    (0..3).filter(|&i| i != dominant).all(|i| i32::from(p[dominant]) - i32::from(p[i]) > 40)
}

/// Pixels of `image` in the scene rectangle x0…x1, y0…y1 (metres of the plan view).
fn pixels_in(image: &image::RgbaImage, (x0, x1): (f32, f32), (y0, y1): (f32, f32)) -> Vec<[u8; 3]> {
    let px = |v: f32| ((v + VIEW_WIDTH / 2.0) * SIZE as f32 / VIEW_WIDTH).clamp(0.0, SIZE as f32) as u32;
    (px(-y1)..px(-y0))
        .flat_map(|row| (px(x0)..px(x1)).map(move |col| (col, row)))
        .map(|(col, row)| {
            let p = image.get_pixel(col, row);
            [p[0], p[1], p[2]]
        })
        .collect()
}

/// Mean ink coverage of a region drawn in `rgb` over paper: how far each pixel has moved from
/// the paper towards the ink, along the channel where they differ most.
fn coverage(pixels: &[[u8; 3]], rgb: [f32; 3]) -> f64 {
    let paper = Style::default().paper.map(|c| c * 255.0);
    let ink = rgb.map(|c| c * 255.0);
    let channel = (0..3).max_by(|&a, &b| (paper[a] - ink[a]).abs().total_cmp(&(paper[b] - ink[b]).abs())).unwrap_or(0);
    let span = f64::from(paper[channel] - ink[channel]);
    let sum: f64 =
        pixels.iter().map(|p| ((f64::from(paper[channel]) - f64::from(p[channel])) / span).clamp(0.0, 1.0)).sum();
    sum / pixels.len().max(1) as f64
}

#[test]
fn a_hatch_colour_darkens_with_the_value_in_its_own_ink() {
    // Values grow eastwards, 0 … 15 over 16 columns of 12.5 m; the range starts at 3, so the
    // west (x < −56 m) is at the bottom of the range.
    let ramp = field(FieldKind::Scalar, 16, 16, 12.5, &[("", &|c, _| c as f64)]);
    let red = [1.0, 0.0, 0.0];
    let mapping =
        Mapping { range: Some([3.0, 15.0]), color: Some(red), ..Mapping::new("ramp", MappingTarget::HatchColor) };
    let image = render(&view("hatch ramp", ramp, mapping, None), &plain_style());
    let paper = on_paper([255; 4]);
    let bottom = pixels_in(&image, (-98.0, -60.0), (-98.0, 98.0));
    assert!(!bottom.is_empty() && bottom.iter().all(|&p| p == paper), "no ink at the bottom of the range");
    // Eastwards from the bottom of the range, in bands of 12.5 m: more and more red ink.
    let bands: Vec<f64> = (0..12)
        .map(|i| {
            let x0 = -56.25 + 12.5 * i as f32;
            coverage(&pixels_in(&image, (x0, x0 + 12.5), (-98.0, 98.0)), red)
        })
        .collect();
    assert!(bands.windows(2).all(|w| w[1] >= w[0] - 0.01), "coverage grows with the value: {bands:?}");
    assert!(bands[0] < 0.05 && bands[11] > 0.5, "from nearly paper to mostly ink: {bands:?}");
    let east = pixels_in(&image, (60.0, 98.0), (-98.0, 98.0));
    let red_ink = east.iter().filter(|&&p| is_ink_of(p, red)).count();
    assert!(red_ink > east.len() / 2, "red-dominant ink in the east: {red_ink} of {}", east.len());
    assert!(east.iter().all(|p| p[0] >= p[1].max(p[2])), "no other colour than red on the paper");
}

#[test]
fn three_fields_as_three_hatch_colours() {
    // Thesis Fig. 9.3: a ramp growing east in red, one growing north in green, a constant
    // middle value in blue — each field in its own ink and stroke direction.
    let (red, green, blue) = ([0.9, 0.1, 0.1], [0.1, 0.7, 0.1], [0.1, 0.2, 0.9]);
    let layer = |key: &str, value: &dyn Fn(usize, usize) -> f64| {
        Arc::new(DataLayer { key: key.into(), field: field(FieldKind::Scalar, 16, 16, 12.5, &[("", value)]) })
    };
    let hatch = |layer: Arc<DataLayer>, range: [f64; 2], color| DataMapping {
        mapping: Mapping {
            range: Some(range),
            color: Some(color),
            ..Mapping::new(&layer.key, MappingTarget::HatchColor)
        },
        layer,
    };
    let data = DataView {
        mappings: vec![
            hatch(layer("east", &|c, _| c as f64), [3.0, 15.0], red),
            hatch(layer("north", &|_, r| 15.0 - r as f64), [3.0, 15.0], green),
            hatch(layer("constant", &|_, _| 1.0), [0.0, 2.0], blue),
        ],
        time: None,
    };
    let image = render(&data, &plain_style());
    assert_matches_reference(&image, &reference("hatch_colors"), 0.03);
    let count = |x, y, rgb| pixels_in(&image, x, y).iter().filter(|&&p| is_ink_of(p, rgb)).count();
    let (west, east, south, north, all) = ((-98.0, -60.0), (60.0, 98.0), (-98.0, -60.0), (60.0, 98.0), (-98.0, 98.0));
    assert_eq!(count(west, all, red), 0, "no red where the east ramp is at its bottom");
    assert!(count(east, all, red) > 300, "red in the east: {}", count(east, all, red));
    assert_eq!(count(all, south, green), 0, "no green where the north ramp is at its bottom");
    assert!(count(all, north, green) > 300, "green in the north: {}", count(all, north, green));
    // The constant field alone in the south-west: blue strokes at its middle darkness.
    let blue_alone = coverage(&pixels_in(&image, west, south), blue);
    assert!((0.3..0.7).contains(&blue_alone), "blue ink covers {blue_alone} of the south-west");
    // (The terrain's object-space strokes are finer than image-space ones at this scale, so
    // fewer pixels show one ink alone.)
    assert!(count(west, north, blue) >= 3 && count(east, south, blue) >= 3, "blue strokes beside green and red");
    // The inks multiply (no field hides another): where all three are high, the crossing
    // strokes are darkest.
    let mean_luminance = |x, y| {
        let pixels = pixels_in(&image, x, y);
        pixels.iter().map(|p| luminance(&image::Rgba([p[0], p[1], p[2], 255]))).sum::<f32>() / pixels.len() as f32
    };
    let north_east = mean_luminance(east, north);
    for (x, y) in [(west, south), (west, north), (east, south)] {
        assert!(north_east < mean_luminance(x, y), "the north-east is darkest: {north_east} vs {x:?} × {y:?}");
    }
}

#[test]
fn abstraction_follows_the_field_per_plant() {
    // Two trees ahead of the camera, one over each half of a field that is 0 in the west and 1
    // in the east (10 m cells, so bilinear sampling is 0 or 1 at the trees): mapped onto abstraction (Table 9.1), the eastern tree's leaves move onto its
    // HLP spheres as with `hlp_abstraction` 1 and the western tree stays as modelled.
    let scene = common::trees_on_a_plain(&[[-12.0, 10.0], [12.0, 10.0]]);
    let renderer = common::full_detail(&scene);
    let camera = scene.default_camera;
    let (w, h) = (160, 120);
    let halves = field(FieldKind::Scalar, 20, 20, 10.0, &[("", &|col, _| if col < 10 { 0.0 } else { 1.0 })]);
    let data = view("halves", halves, Mapping::new("halves", MappingTarget::Abstraction), None);
    let shown = renderer
        .render(FrameRequest::new(&camera, Style::default(), w, h).data(&data))
        .map(|f| f.image)
        .expect("render");
    let as_style = |a: f32| {
        let style = Style { hlp_abstraction: a, ..Style::default() };
        renderer.render(FrameRequest::new(&camera, style, w, h)).map(|f| f.image).expect("render")
    };
    let (modelled, abstract_) = (as_style(0.0), as_style(1.0));
    let differing = |a: &image::RgbaImage, b: &image::RgbaImage, xs: std::ops::Range<u32>| {
        xs.flat_map(|x| (0..h).map(move |y| (x, y))).filter(|&(x, y)| a.get_pixel(x, y) != b.get_pixel(x, y)).count()
    };
    let (west, east) = (0..w / 2, w / 2..w);
    assert!(differing(&modelled, &abstract_, west.clone()) > 200, "abstraction changes the western tree");
    assert!(differing(&modelled, &abstract_, east.clone()) > 200, "abstraction changes the eastern tree");
    assert_eq!(differing(&shown, &modelled, west), 0, "the western tree keeps its leaves");
    assert_eq!(differing(&shown, &abstract_, east), 0, "the eastern tree is abstracted");
}

#[test]
fn too_many_mappings_are_errors() {
    let one = field(FieldKind::Scalar, 1, 1, 200.0, &[("", &|_, _| 1.0)]);
    let layer = Arc::new(DataLayer { key: "one".into(), field: one });
    let mapping = |target| DataMapping { layer: layer.clone(), mapping: Mapping::new("one", target) };
    let four = DataView { mappings: vec![mapping(MappingTarget::Color); 4], time: None };
    let err = plain()
        .1
        .render(FrameRequest::new(&plan(), Style::default(), 16, 16).data(&four))
        .map(|f| f.image)
        .unwrap_err();
    assert!(matches!(err, RenderError::Data(_)) && err.to_string().contains("at most 3"), "{err}");
}

#[test]
fn sample_layers_load_and_lie_on_the_boulder_terrain() {
    use landsketch::fields::{LoadOptions, load_file, load_series};
    let scene = Scene::load(Path::new("data/boulder/scene.toml")).expect("sample scene");
    let hazard = load_file(Path::new("data/boulder/fire_hazard.tif"), &LoadOptions::new(FieldKind::Label)).unwrap();
    assert_eq!(hazard.classes().iter().map(|c| c.value).collect::<Vec<_>>(), [1, 2, 3, 4]);
    let mut steps: Vec<_> = std::fs::read_dir("data/boulder/plume")
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            let stem = p.file_stem().unwrap().to_str().unwrap().trim_start_matches("plume_").to_string();
            (p, format!("{stem}:00:00Z"))
        })
        .collect();
    steps.sort();
    let plume = load_series(&steps, &LoadOptions::new(FieldKind::Scalar)).unwrap();
    assert_eq!(plume.steps().len(), 8);
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
    let camera = Camera::plan(((x0 + x1) / 2.0) as f32, ((y0 + y1) / 2.0) as f32, 2700.0, (x1 - x0) as f32);
    let layer = |key: &str, field| Arc::new(DataLayer { key: key.into(), field });
    let (plume, hazard) = (layer("plume", plume), layer("hazard", hazard));
    let colour = Mapping {
        opacity: 0.8,
        colormap: Some(ColorMapName::YlOrRd),
        range: Some([0.0, 12.0]),
        ..Mapping::new("plume", MappingTarget::Color)
    };
    let data = DataView {
        mappings: vec![
            DataMapping { layer: plume, mapping: colour },
            DataMapping { layer: hazard, mapping: Mapping::new("hazard", MappingTarget::HatchPattern) },
        ],
        time: Some(parse_time("2024-07-01T15:30:00Z").unwrap()),
    };
    let image = renderer
        .render(FrameRequest::new(&camera, Style::default(), 192, 192).data(&data))
        .map(|f| f.image)
        .expect("render");
    assert_matches_reference(&image, &reference("boulder_plume_hazard"), 0.03);
    // The plume is coloured where it is (east-north-east of its source after 3.5 hours) and
    // absent far from it.
    let reddish = image.pixels().filter(|p| i32::from(p[0]) - i32::from(p[2]) > 60).count();
    assert!(reddish > 500, "{reddish} plume pixels");
}
