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
//! one place concentric. The raster is anti-aliased RGBA8, written by the
//! small PNG encoder below (zlib stream of fixed-Huffman deflate blocks,
//! CRC-32 and Adler-32 computed here: no image crate).

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

// ---------------------------------------------------------------------------
// PNG

/// The CRC-32 table (polynomial 0xEDB88320, as PNG and zlib's gzip use).
const CRC_TABLE: [u32; 256] = {
    let mut table = [0u32; 256];
    let mut n = 0;
    while n < 256 {
        let mut c = n as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[n] = c;
        n += 1;
    }
    table
};

/// CRC-32 of `bytes` (ISO 3309, as in PNG chunks).
pub fn crc32(bytes: &[u8]) -> u32 {
    !bytes.iter().fold(!0u32, |c, &b| CRC_TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8))
}

/// Adler-32 of `bytes` (the zlib stream's checksum).
pub fn adler32(bytes: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    // 5552 bytes keep b below 2^32 between reductions.
    for chunk in bytes.chunks(5552) {
        for &x in chunk {
            a += x as u32;
            b += a;
        }
        a %= 65521;
        b %= 65521;
    }
    (b << 16) | a
}

/// Writes bits least significant first, as deflate packs them.
struct BitWriter {
    out: Vec<u8>,
    acc: u64,
    count: u32,
}

impl BitWriter {
    fn bits(&mut self, value: u32, count: u32) {
        self.acc |= (value as u64) << self.count;
        self.count += count;
        while self.count >= 8 {
            self.out.push(self.acc as u8);
            self.acc >>= 8;
            self.count -= 8;
        }
    }

    /// A Huffman code: its bits go most significant first.
    fn code(&mut self, code: u32, length: u32) {
        self.bits(code.reverse_bits() >> (32 - length), length);
    }

    fn flush(&mut self) {
        if self.count > 0 {
            self.bits(0, 8 - self.count);
        }
    }

    /// A literal/length symbol of the fixed Huffman code (RFC 1951 §3.2.6).
    fn fixed_symbol(&mut self, symbol: u32) {
        match symbol {
            0..=143 => self.code(0x30 + symbol, 8),
            144..=255 => self.code(0x190 + symbol - 144, 9),
            256..=279 => self.code(symbol - 256, 7),
            _ => self.code(0xc0 + symbol - 280, 8),
        }
    }
}

const LENGTH_BASE: [u32; 29] =
    [3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258];
const LENGTH_EXTRA: [u32; 29] = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0];
const DISTANCE_BASE: [u32; 30] = [
    1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537, 2049, 3073, 4097, 6145,
    8193, 12289, 16385, 24577,
];
const DISTANCE_EXTRA: [u32; 30] =
    [0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13];

/// The last index whose base is at most `value`.
fn bucket(bases: &[u32], value: u32) -> usize {
    bases.iter().rposition(|&b| b <= value).expect("value at least the first base")
}

/// A raw deflate stream of `data`: one fixed-Huffman block whose matches are
/// repeats at the few `distances` given (for an image: the previous pixel,
/// the pixel above), greedy, longest first.
fn deflate_fixed(data: &[u8], distances: &[usize]) -> Vec<u8> {
    let mut w = BitWriter { out: Vec::with_capacity(data.len() / 8 + 64), acc: 0, count: 0 };
    w.bits(1, 1); // BFINAL
    w.bits(1, 2); // BTYPE = 01: fixed Huffman codes
    let mut i = 0;
    while i < data.len() {
        let mut best = (0, 0);
        for &d in distances {
            if d == 0 || d > i || d > 32768 {
                continue;
            }
            let limit = (data.len() - i).min(258);
            let length = (0..limit).take_while(|&k| data[i + k] == data[i + k - d]).count();
            if length > best.0 {
                best = (length, d);
            }
        }
        let (length, distance) = best;
        if length >= 3 {
            let l = bucket(&LENGTH_BASE, length as u32);
            w.fixed_symbol(257 + l as u32);
            w.bits(length as u32 - LENGTH_BASE[l], LENGTH_EXTRA[l]);
            let d = bucket(&DISTANCE_BASE, distance as u32);
            w.code(d as u32, 5);
            w.bits(distance as u32 - DISTANCE_BASE[d], DISTANCE_EXTRA[d]);
            i += length;
        } else {
            w.fixed_symbol(data[i] as u32);
            i += 1;
        }
    }
    w.fixed_symbol(256);
    w.flush();
    w.out
}

/// A zlib stream (RFC 1950) of `data`, deflated with repeats at `distances`.
fn zlib(data: &[u8], distances: &[usize]) -> Vec<u8> {
    // CMF: deflate, 32 KiB window; FLG: no dictionary, level 0, check bits.
    let mut out = vec![0x78, 0x01];
    out.extend(deflate_fixed(data, distances));
    out.extend(adler32(data).to_be_bytes());
    out
}

fn chunk(png: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    png.extend((data.len() as u32).to_be_bytes());
    let start = png.len();
    png.extend(kind);
    png.extend(data);
    let crc = crc32(&png[start..]);
    png.extend(crc.to_be_bytes());
}

/// The PNG (8-bit RGBA, not interlaced) of `rgba`: `height` rows of `width`
/// pixels of 4 bytes each.
pub fn encode_png(width: u32, height: u32, rgba: &[u8]) -> Vec<u8> {
    let row = width as usize * 4;
    assert_eq!(rgba.len(), row * height as usize, "{width}x{height} RGBA8 takes {} bytes", row * height as usize);
    // Filter type 0 (None) on every row; the deflate matches at 4 bytes
    // back and one row up do what the Sub and Up filters would.
    let mut raw = Vec::with_capacity((row + 1) * height as usize);
    for line in rgba.chunks(row) {
        raw.push(0);
        raw.extend_from_slice(line);
    }
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    let mut header = Vec::with_capacity(13);
    header.extend(width.to_be_bytes());
    header.extend(height.to_be_bytes());
    header.extend([8, 6, 0, 0, 0]); // bit depth 8, RGBA, deflate, filtering 0, no interlace
    chunk(&mut png, b"IHDR", &header);
    chunk(&mut png, b"IDAT", &zlib(&raw, &[4, row + 1, 1]));
    chunk(&mut png, b"IEND", &[]);
    png
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inflates a zlib stream of stored and fixed-Huffman blocks (what
    /// [`zlib`] writes), checking header and Adler-32.
    fn inflate(z: &[u8]) -> Vec<u8> {
        assert_eq!((z[0] as u32 * 256 + z[1] as u32) % 31, 0, "zlib header check bits");
        assert_eq!(z[0] & 0x0f, 8, "deflate");
        let data = &z[2..z.len() - 4];
        let mut pos = 0usize; // bit position
        let mut bit = |n: u32| {
            let mut v = 0u32;
            for k in 0..n {
                v |= (((data[pos / 8] >> (pos % 8)) & 1) as u32) << k;
                pos += 1;
            }
            v
        };
        let mut out: Vec<u8> = Vec::new();
        loop {
            let last = bit(1);
            let kind = bit(2);
            assert_eq!(kind, 1, "only fixed-Huffman blocks are written");
            loop {
                // Huffman codes come most significant bit first.
                let mut code = 0u32;
                for _ in 0..7 {
                    code = (code << 1) | bit(1);
                }
                let symbol = if code <= 0x17 {
                    256 + code
                } else {
                    code = (code << 1) | bit(1);
                    match code {
                        0x30..=0xbf => code - 0x30,
                        0xc0..=0xc7 => 280 + code - 0xc0,
                        _ => {
                            code = (code << 1) | bit(1);
                            assert!((0x190..=0x1ff).contains(&code));
                            144 + code - 0x190
                        }
                    }
                };
                match symbol {
                    0..=255 => out.push(symbol as u8),
                    256 => break,
                    _ => {
                        let l = (symbol - 257) as usize;
                        let length = LENGTH_BASE[l] + bit(LENGTH_EXTRA[l]);
                        let mut d = 0u32;
                        for _ in 0..5 {
                            d = (d << 1) | bit(1);
                        }
                        let distance = (DISTANCE_BASE[d as usize] + bit(DISTANCE_EXTRA[d as usize])) as usize;
                        for _ in 0..length {
                            out.push(out[out.len() - distance]);
                        }
                    }
                }
            }
            if last == 1 {
                break;
            }
        }
        assert_eq!(&z[z.len() - 4..], adler32(&out).to_be_bytes(), "Adler-32");
        out
    }

    /// The chunks of a PNG: (type, data), every CRC checked.
    fn chunks(png: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "signature");
        let mut rest = &png[8..];
        let mut out = Vec::new();
        while !rest.is_empty() {
            let length = u32::from_be_bytes(rest[..4].try_into().unwrap()) as usize;
            let kind: [u8; 4] = rest[4..8].try_into().unwrap();
            let crc = u32::from_be_bytes(rest[8 + length..12 + length].try_into().unwrap());
            assert_eq!(crc, crc32(&rest[4..8 + length]), "CRC of {}", String::from_utf8_lossy(&kind));
            out.push((kind, rest[8..8 + length].to_vec()));
            rest = &rest[12 + length..];
        }
        out
    }

    #[test]
    fn checksums_match_their_check_values() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        assert_eq!(adler32(b"Wikipedia"), 0x11E6_0398);
        assert_eq!(adler32(&[]), 1);
        // Long runs of 0xff: the reductions keep the sums exact.
        let ones = vec![0xffu8; 100_000];
        let (mut a, mut b) = (1u64, 0u64);
        for &x in &ones {
            a = (a + x as u64) % 65521;
            b = (b + a) % 65521;
        }
        assert_eq!(adler32(&ones), ((b << 16) | a) as u32);
    }

    #[test]
    fn deflate_round_trips() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut noise = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 56) as u8
        };
        let random: Vec<u8> = (0..5000).map(|_| noise()).collect();
        let runs: Vec<u8> = (0..70_000).map(|i| if (i / 300) % 3 == 0 { 7 } else { (i % 5) as u8 }).collect();
        for data in [Vec::new(), vec![42], random, runs] {
            assert_eq!(inflate(&zlib(&data, &[4, 1, 1025])), data);
        }
    }

    #[test]
    fn png_has_signature_chunks_and_header() {
        let (w, h) = (5u32, 3u32);
        let rgba: Vec<u8> = (0..w * h * 4).map(|i| (i * 37 % 251) as u8).collect();
        let png = encode_png(w, h, &rgba);
        let chunks = chunks(&png);
        let kinds: Vec<&[u8; 4]> = chunks.iter().map(|(k, _)| k).collect();
        assert_eq!(kinds, [b"IHDR", b"IDAT", b"IEND"]);
        let header = &chunks[0].1;
        assert_eq!(header.len(), 13);
        assert_eq!(u32::from_be_bytes(header[0..4].try_into().unwrap()), w);
        assert_eq!(u32::from_be_bytes(header[4..8].try_into().unwrap()), h);
        assert_eq!(&header[8..], [8, 6, 0, 0, 0]);
        let raw = inflate(&chunks[1].1);
        assert_eq!(raw.len(), (1 + 4 * w as usize) * h as usize);
        for (y, line) in raw.chunks(1 + 4 * w as usize).enumerate() {
            assert_eq!(line[0], 0, "filter type None");
            assert_eq!(&line[1..], &rgba[y * 4 * w as usize..(y + 1) * 4 * w as usize]);
        }
    }

    fn colours(rgba: &[u8]) -> std::collections::BTreeSet<[u8; 3]> {
        rgba.chunks(4).filter(|p| p[3] == 255).map(|p| [p[0], p[1], p[2]]).collect()
    }

    #[test]
    fn icon_shows_the_chain_in_drive_colours() {
        let reference = Model::reference_rrpr();
        let rgba = draw_chain(&reference, ICON_SIZE);
        let seen = colours(&rgba);
        for c in [DRIVE_COLOURS[0], DRIVE_COLOURS[1], LINK, BACKGROUND, OUTLINE] {
            assert!(seen.contains(&c), "{c:?} not drawn");
        }
        assert!(!seen.contains(&DRIVE_COLOURS[2]), "no motor drive in the reference arm");
        let motor = draw_chain(&Model::reference_rrpr_motor(), ICON_SIZE);
        assert!(colours(&motor).contains(&DRIVE_COLOURS[2]));
        // Corners outside the rounded frame stay transparent.
        assert_eq!(rgba[3], 0);
        let png = model_icon(&reference);
        let chunks = chunks(&png);
        assert_eq!(inflate(&chunks[1].1).len(), (1 + 4 * ICON_SIZE as usize) * ICON_SIZE as usize);
        assert!(png.len() < 64 * 1024, "{} bytes", png.len());
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
