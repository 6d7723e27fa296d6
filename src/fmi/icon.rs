//! `model.png`: the FMU's icon (FMI 2.0 §2.3, at the archive's root), drawn
//! from the model: a side view of the chain at q = 0.
//!
//! The frame origins come from the joint placements (the joints' motions at
//! q = 0 are their constant offsets). The view is the vertical plane (up =
//! against gravity) along the horizontal direction in which the chain spreads
//! most; without gravity the plane of its two largest spreads. Links are
//! thick lines from joint to joint and to the end point E, with a thinner
//! line from each link's frame origin to its centre of mass (where its body
//! reaches beyond the chain, e.g. the rod of a prismatic joint); joints are
//! circles (revolute) or squares (prismatic) in the colour of their drive
//! ([`DRIVE_COLOURS`]: rigid grey, flexible blue, motor orange), joints at
//! one place concentric. The raster is anti-aliased RGBA8, written as a PNG
//! by the `png` crate.

use super::description::{drive_colour_index, DRIVE_COLOURS};
use crate::math::{Mat3, Vec3};
use crate::model::{JointKind, Model, Placement};

/// Width and height of `model.png`, pixels.
pub const ICON_SIZE: u32 = 256;

/// The PNG file `model.png` of the FMU for `model`.
pub fn model_icon(model: &Model) -> Vec<u8> {
    let size = ICON_SIZE;
    encode_png(size, size, &draw_chain(model, size))
}

/// Points of the chain at q = 0 in the base frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPoints {
    /// Origin of each joint frame (on the joint axis), in chain order.
    pub joints: Vec<Vec3>,
    /// Origin of each link frame (after the joint's motion at q = 0).
    pub link_origins: Vec<Vec3>,
    /// Centre of mass of each link.
    pub centres_of_mass: Vec<Vec3>,
    /// The end point E.
    pub end_point: Vec3,
}

/// The frame origins of `model` at q = 0: B_i = B_{i−1} · P_i · M_i(0).
pub fn chain_points(model: &Model) -> ChainPoints {
    let mut frame = Placement::identity();
    let mut points = ChainPoints {
        joints: Vec::new(),
        link_origins: Vec::new(),
        centres_of_mass: Vec::new(),
        end_point: Vec3::zeros(),
    };
    for (joint, link) in model.joints.iter().zip(&model.links) {
        let joint_frame = frame.then(&joint.placement);
        let motion = match joint.kind {
            JointKind::Revolute => {
                let (s, c) = joint.offset.sin_cos();
                Placement { rotation: Mat3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0), translation: Vec3::zeros() }
            }
            JointKind::Prismatic => {
                Placement { rotation: Mat3::identity(), translation: Vec3::new(0.0, 0.0, joint.offset) }
            }
        };
        frame = joint_frame.then(&motion);
        points.joints.push(joint_frame.translation);
        points.link_origins.push(frame.translation);
        points.centres_of_mass.push(frame.apply(&link.com));
    }
    points.end_point = frame.apply(&model.end_point);
    points
}

/// The two unit vectors (right, up) of the view plane for `points`, seen
/// with gravity `gravity` pointing down.
fn view_plane(points: &[Vec3], gravity: &Vec3) -> (Vec3, Vec3) {
    let mean = points.iter().fold(Vec3::zeros(), |a, p| a + p) / points.len().max(1) as f64;
    let spread = |project: &dyn Fn(&Vec3) -> Vec3| {
        points.iter().fold(Mat3::zeros(), |c, p| {
            let d = project(&(p - mean));
            c + d * d.transpose()
        })
    };
    // Eigenvectors by decreasing eigenvalue.
    let principal = |c: Mat3| {
        let eig = c.symmetric_eigen();
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        (order.map(|k| eig.eigenvectors.column(k).into_owned()), order.map(|k| eig.eigenvalues[k]))
    };
    let (right, up) = if gravity.norm() > 1e-9 {
        let up = -gravity.normalize();
        let (vectors, values) = principal(spread(&|d: &Vec3| d - up * up.dot(d)));
        let right = if values[0] > 1e-12 {
            vectors[0]
        } else {
            // A vertical chain: any horizontal direction.
            let x = if up.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
            (x - up * up.dot(&x)).normalize()
        };
        (right, up)
    } else {
        let (vectors, values) = principal(spread(&|d: &Vec3| *d));
        if values[1] > 1e-12 {
            (vectors[0], vectors[1])
        } else {
            (Vec3::x(), Vec3::z())
        }
    };
    // The chain reaches to the right.
    let reach = points.last().map_or(0.0, |p| (p - points[0]).dot(&right));
    (if reach < 0.0 { -right } else { right }, up)
}

/// An RGBA canvas with "over" compositing of anti-aliased shapes given by
/// their signed distance (negative inside), in pixels.
struct Canvas {
    size: usize,
    /// Straight (not premultiplied) RGBA in [0, 1].
    pixels: Vec<[f32; 4]>,
}

impl Canvas {
    fn new(size: usize) -> Canvas {
        Canvas { size, pixels: vec![[0.0; 4]; size * size] }
    }

    /// Fills the pixels whose centres `distance` puts inside, within the box
    /// [x0, x1] × [y0, y1], with `colour` (`alpha` its opacity).
    fn fill(&mut self, bounds: [f64; 4], colour: [u8; 3], alpha: f32, distance: impl Fn(f64, f64) -> f64) {
        let n = self.size as f64;
        let [x0, x1, y0, y1] = bounds.map(|b| b.clamp(0.0, n));
        for y in (y0.floor() as usize)..(y1.ceil() as usize).min(self.size) {
            for x in (x0.floor() as usize)..(x1.ceil() as usize).min(self.size) {
                let d = distance(x as f64 + 0.5, y as f64 + 0.5);
                let cover = (0.5 - d).clamp(0.0, 1.0) as f32 * alpha;
                if cover <= 0.0 {
                    continue;
                }
                let dst = &mut self.pixels[y * self.size + x];
                let out_alpha = cover + dst[3] * (1.0 - cover);
                for k in 0..3 {
                    let src = colour[k] as f32 / 255.0;
                    dst[k] = (src * cover + dst[k] * dst[3] * (1.0 - cover)) / out_alpha;
                }
                dst[3] = out_alpha;
            }
        }
    }

    fn circle(&mut self, c: [f64; 2], r: f64, colour: [u8; 3]) {
        self.fill([c[0] - r - 1.0, c[0] + r + 1.0, c[1] - r - 1.0, c[1] + r + 1.0], colour, 1.0, |x, y| {
            (x - c[0]).hypot(y - c[1]) - r
        });
    }

    /// An axis-aligned square of half side `h`, corners rounded by `round`.
    fn square(&mut self, c: [f64; 2], h: f64, round: f64, colour: [u8; 3]) {
        self.rounded_box(c, [h, h], round, colour, 1.0);
    }

    fn rounded_box(&mut self, c: [f64; 2], half: [f64; 2], round: f64, colour: [u8; 3], alpha: f32) {
        let bounds = [c[0] - half[0] - 1.0, c[0] + half[0] + 1.0, c[1] - half[1] - 1.0, c[1] + half[1] + 1.0];
        self.fill(bounds, colour, alpha, |x, y| {
            let qx = (x - c[0]).abs() - half[0] + round;
            let qy = (y - c[1]).abs() - half[1] + round;
            qx.max(0.0).hypot(qy.max(0.0)) + qx.max(qy).min(0.0) - round
        });
    }

    /// A segment from `a` to `b` with round ends, `r` its half width.
    fn line(&mut self, a: [f64; 2], b: [f64; 2], r: f64, colour: [u8; 3]) {
        let bounds =
            [a[0].min(b[0]) - r - 1.0, a[0].max(b[0]) + r + 1.0, a[1].min(b[1]) - r - 1.0, a[1].max(b[1]) + r + 1.0];
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let length2 = dx * dx + dy * dy;
        self.fill(bounds, colour, 1.0, |x, y| {
            let t = if length2 > 0.0 { (((x - a[0]) * dx + (y - a[1]) * dy) / length2).clamp(0.0, 1.0) } else { 0.0 };
            (x - a[0] - t * dx).hypot(y - a[1] - t * dy) - r
        });
    }

    fn rgba8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
    }
}

const BACKGROUND: [u8; 3] = [0xf4, 0xf6, 0xf8];
const FRAME: [u8; 3] = [0xc8, 0xd0, 0xd8];
const GROUND: [u8; 3] = [0x4a, 0x52, 0x5a];
const LINK: [u8; 3] = [0x2f, 0x3d, 0x4a];
const BODY: [u8; 3] = [0x9a, 0xa8, 0xb4];
const OUTLINE: [u8; 3] = [0x1d, 0x22, 0x28];

/// The icon of `model` as RGBA8 rows, `size` × `size` pixels.
pub fn draw_chain(model: &Model, size: u32) -> Vec<u8> {
    let n = size as f64;
    let points = chain_points(model);
    let mut all = vec![Vec3::zeros()];
    all.extend(points.joints.iter().chain(&points.link_origins).chain(&points.centres_of_mass));
    all.push(points.end_point);
    let (right, up) = view_plane(&all, &model.gravity);
    let project = |p: &Vec3| [p.dot(&right), p.dot(&up)];
    let uv: Vec<[f64; 2]> = all.iter().map(project).collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &uv {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let span = if span > 1e-9 { span } else { 1.0 };
    // Room for the symbols and the ground at the edges.
    let margin = 0.17 * n;
    let scale = (n - 2.0 * margin) / span;
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let pixel = |p: &Vec3| {
        let [u, v] = project(p);
        [n / 2.0 + (u - centre[0]) * scale, n / 2.0 - (v - centre[1]) * scale]
    };

    let mut canvas = Canvas::new(size as usize);
    let corner = n * 0.09;
    canvas.rounded_box([n / 2.0, n / 2.0], [n / 2.0, n / 2.0], corner, FRAME, 1.0);
    canvas.rounded_box(
        [n / 2.0, n / 2.0],
        [n / 2.0 - n / 128.0, n / 2.0 - n / 128.0],
        corner - n / 128.0,
        BACKGROUND,
        1.0,
    );

    let link_r = n / 48.0;
    // Joints about as large as their spacing allows (joints at one place aside).
    let full_r = n / 15.0;
    let joint_pixels: Vec<[f64; 2]> = points.joints.iter().map(pixel).collect();
    let mut spacing = f64::INFINITY;
    for (k, a) in joint_pixels.iter().enumerate() {
        for b in &joint_pixels[k + 1..] {
            let d = (a[0] - b[0]).hypot(a[1] - b[1]);
            if d >= 0.25 * full_r {
                spacing = spacing.min(d);
            }
        }
    }
    let joint_r = (0.6 * spacing).clamp(n / 30.0, full_r);
    let base = pixel(&Vec3::zeros());
    // The ground under the base.
    canvas.rounded_box([base[0], base[1] + full_r * 0.55], [full_r * 1.9, full_r * 0.42], full_r * 0.15, GROUND, 1.0);

    // Bodies beyond the chain: link origin to centre of mass.
    for (origin, com) in points.link_origins.iter().zip(&points.centres_of_mass) {
        canvas.line(pixel(origin), pixel(com), link_r * 0.8, BODY);
        canvas.circle(pixel(com), link_r * 1.3, BODY);
    }
    // The chain: base, joint i, link origin i, joint i + 1, …, E.
    let mut chain = vec![base];
    for (joint, origin) in points.joints.iter().zip(&points.link_origins) {
        chain.push(pixel(joint));
        chain.push(pixel(origin));
    }
    let end = pixel(&points.end_point);
    chain.push(end);
    for pair in chain.windows(2) {
        canvas.line(pair[0], pair[1], link_r, LINK);
    }
    // The end point: a small open ring.
    canvas.circle(end, link_r * 2.0, LINK);
    canvas.circle(end, link_r * 0.9, BACKGROUND);

    // Joints: earlier ones at the same place stay visible as rings.
    let mut drawn: Vec<[f64; 2]> = Vec::new();
    for (joint, &c) in model.joints.iter().zip(&joint_pixels) {
        let under = drawn.iter().filter(|d| (d[0] - c[0]).hypot(d[1] - c[1]) < 0.5 * joint_r).count();
        let r = joint_r * 0.66f64.powi(under as i32);
        let outline = (n / 96.0).max(1.0);
        let colour = DRIVE_COLOURS[drive_colour_index(&joint.drive)];
        match joint.kind {
            JointKind::Revolute => {
                canvas.circle(c, r, OUTLINE);
                canvas.circle(c, r - outline, colour);
            }
            JointKind::Prismatic => {
                let h = r * 0.9;
                canvas.square(c, h, h * 0.15, OUTLINE);
                canvas.square(c, h - outline, (h - outline) * 0.15, colour);
            }
        }
        drawn.push(c);
    }
    canvas.rgba8()
}

/// The PNG (8-bit RGBA, not interlaced) of `rgba`: `height` rows of `width`
/// pixels of 4 bytes each. The `png` crate chooses each row's filter
/// (adaptive) and deflates at level 9 through flate2, whose zlib-rs backend
/// also deflates the `.fmu` archive; crc32fast sums the chunks.
fn encode_png(width: u32, height: u32, rgba: &[u8]) -> Vec<u8> {
    let row = width as usize * 4;
    assert_eq!(rgba.len(), row * height as usize, "{width}x{height} RGBA8 takes {} bytes", row * height as usize);
    let mut png = Vec::new();
    let mut encoder = png::Encoder::new(&mut png, width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::High);
    // Writing into memory fails only on arguments, which are checked above.
    let mut writer = encoder.write_header().expect("a valid PNG header");
    writer.write_image_data(rgba).expect("RGBA8 of the declared size");
    writer.finish().expect("the image is complete");
    png
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The width, height and RGBA8 rows of `png`, decoded with every checksum
    /// checked (the chunks' CRC-32, the zlib stream's Adler-32).
    fn decode(png: &[u8]) -> (u32, u32, Vec<u8>) {
        let mut decoder = png::Decoder::new(std::io::Cursor::new(png));
        decoder.ignore_checksums(false);
        let mut reader = decoder.read_info().expect("a PNG header");
        let info = reader.info();
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgba, png::BitDepth::Eight));
        assert!(!info.interlaced);
        let (width, height) = (info.width, info.height);
        let mut rgba = vec![0; reader.output_buffer_size().expect("a small image")];
        let frame = reader.next_frame(&mut rgba).expect("valid image data");
        rgba.truncate(frame.buffer_size());
        reader.finish().expect("a complete PNG");
        (width, height, rgba)
    }

    #[test]
    fn png_decodes_to_the_pixels_encoded() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut noise = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 56) as u8
        };
        let random: Vec<u8> = (0..64 * 48 * 4).map(|_| noise()).collect();
        let pattern: Vec<u8> = (0..5 * 3 * 4).map(|i| (i * 37 % 251) as u8).collect();
        for (w, h, rgba) in [(1, 1, vec![1, 2, 3, 4]), (5, 3, pattern), (64, 48, random)] {
            assert_eq!(decode(&encode_png(w, h, &rgba)), (w, h, rgba));
        }
    }

    /// The icon's pixels are the rendering's, exactly: the encoder loses
    /// nothing (the hand-written encoder it replaced wrote the same pixels).
    #[test]
    fn icon_is_the_rendering_of_the_chain() {
        for model in [Model::reference_rrpr(), Model::reference_rrpr_motor()] {
            let png = model_icon(&model);
            assert_eq!(decode(&png), (ICON_SIZE, ICON_SIZE, draw_chain(&model, ICON_SIZE)), "{}", model.name);
            assert!(png.len() < 64 * 1024, "{} bytes", png.len());
        }
    }

    fn colours(rgba: &[u8]) -> std::collections::BTreeSet<[u8; 3]> {
        rgba.chunks(4).filter(|p| p[3] == 255).map(|p| [p[0], p[1], p[2]]).collect()
    }

    #[test]
    fn icon_shows_the_chain_in_drive_colours() {
        let rgba = draw_chain(&Model::reference_rrpr(), ICON_SIZE);
        let seen = colours(&rgba);
        for c in [DRIVE_COLOURS[0], DRIVE_COLOURS[1], LINK, BACKGROUND, OUTLINE] {
            assert!(seen.contains(&c), "{c:?} not drawn");
        }
        assert!(!seen.contains(&DRIVE_COLOURS[2]), "no motor drive in the reference arm");
        let motor = draw_chain(&Model::reference_rrpr_motor(), ICON_SIZE);
        assert!(colours(&motor).contains(&DRIVE_COLOURS[2]));
        // Corners outside the rounded frame stay transparent.
        assert_eq!(rgba[3], 0);
    }

    #[test]
    fn frame_origins_follow_the_placements() {
        // The reference arm at q = 0: the column of 0.6 m, then joint 4 0.1 m along z3 and E 0.1 m beyond.
        let p = chain_points(&Model::reference_rrpr());
        assert!((p.joints[0] - Vec3::new(0.0, 0.0, 0.6)).norm() < 1e-12, "{:?}", p.joints[0]);
        assert!((p.joints[1] - p.joints[0]).norm() < 1e-12);
        assert!(((p.joints[3] - p.joints[2]).norm() - 0.1).abs() < 1e-12);
        assert!(((p.end_point - p.link_origins[3]).norm() - 0.1).abs() < 1e-12);
    }
}
