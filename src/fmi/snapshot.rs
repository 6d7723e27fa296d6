//! The byte format of an FMU state (fmi2GetFMUstate and the serialized form
//! are the same bytes): versioned, pointer-free, little-endian.
//!
//! ```text
//! offset  size  field
//! 0       8     magic "SSMFMUst"
//! 8       4     format version (u32) = 3 (VERSION)
//! 12      16    model hash (u128): model file + variable layout, see description::model_hash
//! 28      8     payload length L (u64)
//! 36      L     payload
//! 36+L    8     FNV-1a 64 checksum of bytes 0 .. 36+L
//! ```
//!
//! Payload, n joints, m motor drives, f64 as IEEE bits: life-cycle state
//! (u8); start time; stop time (u8 flag + f64); n (u32); m (u32); inputs
//! q*, q̇*, q̈* (3n); motor torques τ_m and their two derivatives (3n);
//! start values (u8 flag, n q, n q̇, n θ_m, n θ̇_m, u8 static start); the
//! parameter and setting variables in layout order (u32 count + values);
//! the engine [`State`] field by field (per-coordinate fields with n + m
//! entries, phases as tag + direction bytes, counters as u64).
//!
//! Written field by field, not by a serde format crate (bincode, postcard):
//! this layout is the FMU's versioned interchange format, exchanged between
//! the linux64, win64 and darwin64 binaries, and such a crate would need
//! serde on the engine's types (which know nothing of FMI) and leave the
//! layout to its own versions. The exhaustive destructuring in `put_state`
//! keeps every field of [`State`] in it.

use super::description::fnv1a_64;
use super::lifecycle::LifeCycle;
use crate::math::Vec3;
use crate::stepper::{Energy, Phase, State, StepStatistics};

const MAGIC: [u8; 8] = *b"SSMFMUst";
const VERSION: u32 = 3;
const HEADER: usize = 36;
const CHECKSUM: usize = 8;

/// Everything that decides the continuation of an instance.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Snapshot {
    pub(crate) lifecycle: LifeCycle,
    pub(crate) start_time: f64,
    pub(crate) stop_time: Option<f64>,
    /// q*, q̇*, q̈* as set by the master.
    pub(crate) inputs: [Vec<f64>; 3],
    /// τ_m and its two derivatives as set by the master.
    pub(crate) torques: [Vec<f64>; 3],
    pub(crate) use_start_values: bool,
    pub(crate) q_start: Vec<f64>,
    pub(crate) qd_start: Vec<f64>,
    pub(crate) theta_m_start: Vec<f64>,
    pub(crate) omega_m_start: Vec<f64>,
    pub(crate) static_start: bool,
    /// Values of the parameter and setting variables, in layout order.
    pub(crate) parameters: Vec<f64>,
    /// The engine state.
    pub(crate) state: State,
}

/// Encodes `s` for a model with fingerprint `model_hash`.
pub(crate) fn encode(s: &Snapshot, model_hash: u128) -> Vec<u8> {
    let mut p = Writer::default();
    p.u8(s.lifecycle.code());
    p.f64(s.start_time);
    p.u8(u8::from(s.stop_time.is_some()));
    p.f64(s.stop_time.unwrap_or(0.0));
    p.u32(s.state.nq() as u32);
    p.u32((s.state.n_coordinates() - s.state.nq()) as u32);
    s.inputs.iter().for_each(|v| p.f64s(v));
    s.torques.iter().for_each(|v| p.f64s(v));
    p.u8(u8::from(s.use_start_values));
    p.f64s(&s.q_start);
    p.f64s(&s.qd_start);
    p.f64s(&s.theta_m_start);
    p.f64s(&s.omega_m_start);
    p.u8(u8::from(s.static_start));
    p.u32(s.parameters.len() as u32);
    p.f64s(&s.parameters);
    put_state(&mut p, &s.state);

    let mut out = Writer(Vec::with_capacity(HEADER + p.0.len() + CHECKSUM));
    out.0.extend_from_slice(&MAGIC);
    out.u32(VERSION);
    out.0.extend_from_slice(&model_hash.to_le_bytes());
    out.u64(p.0.len() as u64);
    out.0.extend_from_slice(&p.0);
    let checksum = fnv1a_64(&out.0);
    out.u64(checksum);
    out.0
}

/// Decodes bytes made by [`encode`] for the same model (`model_hash`, `n`
/// joints, `m` motor drives, `n_parameters` parameter variables). Every
/// corrupted, truncated, padded or foreign buffer is rejected with the reason.
pub(crate) fn decode(
    bytes: &[u8],
    model_hash: u128,
    n: usize,
    m: usize,
    n_parameters: usize,
) -> Result<Snapshot, String> {
    if bytes.len() < HEADER + CHECKSUM {
        return Err(format!("truncated: {} bytes, an FMU state has at least {}", bytes.len(), HEADER + CHECKSUM));
    }
    if bytes[..8] != MAGIC {
        return Err("not an FMU state of this FMU (wrong magic bytes)".into());
    }
    let mut header = Reader { bytes: &bytes[8..HEADER], at: 0 };
    let version = header.u32()?;
    if version != VERSION {
        return Err(format!("format version {version}; this FMU reads version {VERSION}"));
    }
    let hash = u128::from_le_bytes(header.take(16)?.try_into().expect("16 bytes"));
    let length = header.u64()?;
    let expected = (HEADER + CHECKSUM) as u64 + length;
    if bytes.len() as u64 != expected {
        return Err(format!("{} bytes, but the header announces {expected}: truncated or padded", bytes.len()));
    }
    let (body, checksum) = bytes.split_at(bytes.len() - CHECKSUM);
    if fnv1a_64(body) != u64::from_le_bytes(checksum.try_into().expect("8 bytes")) {
        return Err("checksum mismatch: the bytes are corrupted".into());
    }
    if hash != model_hash {
        return Err(format!(
            "state of another model or FMU version (model hash {hash:032x}, this FMU has {model_hash:032x})"
        ));
    }
    let mut r = Reader { bytes: &body[HEADER..], at: 0 };
    let s = read_payload(&mut r, n, m, n_parameters)?;
    if r.at != r.bytes.len() {
        return Err(format!("{} unread bytes at the end of the payload", r.bytes.len() - r.at));
    }
    Ok(s)
}

fn read_payload(r: &mut Reader, n: usize, m: usize, n_parameters: usize) -> Result<Snapshot, String> {
    let code = r.u8()?;
    let lifecycle = LifeCycle::from_code(code).ok_or_else(|| format!("unknown life-cycle state {code}"))?;
    let start_time = r.f64()?;
    let has_stop = r.flag()?;
    let stop = r.f64()?;
    let joints = r.u32()? as usize;
    if joints != n {
        return Err(format!("state of a {joints}-joint model; this model has {n} joints"));
    }
    let rotors = r.u32()? as usize;
    if rotors != m {
        return Err(format!("state of a model with {rotors} motor drives; this model has {m}"));
    }
    let inputs = [r.f64s(n)?, r.f64s(n)?, r.f64s(n)?];
    let torques = [r.f64s(n)?, r.f64s(n)?, r.f64s(n)?];
    let use_start_values = r.flag()?;
    let q_start = r.f64s(n)?;
    let qd_start = r.f64s(n)?;
    let theta_m_start = r.f64s(n)?;
    let omega_m_start = r.f64s(n)?;
    let static_start = r.flag()?;
    let count = r.u32()? as usize;
    if count != n_parameters {
        return Err(format!("{count} parameter values; this model has {n_parameters}"));
    }
    let parameters = r.f64s(count)?;
    let state = get_state(r, n, m)?;
    Ok(Snapshot {
        lifecycle,
        start_time,
        stop_time: has_stop.then_some(stop),
        inputs,
        torques,
        use_start_values,
        q_start,
        qd_start,
        theta_m_start,
        omega_m_start,
        static_start,
        parameters,
        state,
    })
}

/// Writes every field of `s`; the exhaustive destructuring makes a new field
/// of [`State`] or [`Energy`] a compile error here until it is serialized.
fn put_state(w: &mut Writer, s: &State) {
    let State {
        time,
        q,
        qd,
        qdd,
        phase,
        q_star,
        qd_star,
        drive_force,
        damping_force,
        friction_force,
        normal_load,
        lever_load,
        margin,
        clearance_margin,
        reaction_force,
        reaction_moment,
        stick_count,
        stuck_time,
        motor_torque,
        gear_torque,
        energy,
        end_point,
        end_point_rigid,
        steps,
    } = s;
    let StepStatistics { accepted, rejected, last_h, next_h } = steps;
    let Energy { kinetic, potential, spring, drive_work, friction_heat, damping_heat, rotor_kinetic, motor_heat } =
        energy;
    w.f64(*time);
    for v in [q, qd, qdd] {
        w.f64s(v);
    }
    for p in phase {
        let (tag, direction) = match *p {
            Phase::Prescribed => (0, 0),
            Phase::Stuck => (1, 0),
            Phase::Slipping(d) => (2, d),
        };
        w.u8(tag);
        w.0.extend_from_slice(&direction.to_le_bytes());
    }
    for v in
        [q_star, qd_star, drive_force, damping_force, friction_force, normal_load, lever_load, margin, clearance_margin]
    {
        w.f64s(v);
    }
    for v in [reaction_force, reaction_moment] {
        v.iter().for_each(|x| w.f64s(x.as_slice()));
    }
    stick_count.iter().for_each(|c| w.u64(*c));
    w.f64s(stuck_time);
    w.f64s(motor_torque);
    w.f64s(gear_torque);
    w.f64s(&[*kinetic, *potential, *spring, *drive_work, *friction_heat, *damping_heat, *rotor_kinetic, *motor_heat]);
    w.f64s(end_point.as_slice());
    w.f64s(end_point_rigid.as_slice());
    w.u64(*accepted);
    w.u64(*rejected);
    w.f64s(&[*last_h, *next_h]);
}

fn get_state(r: &mut Reader, n: usize, m: usize) -> Result<State, String> {
    let nc = n + m;
    let time = r.f64()?;
    let (q, qd, qdd) = (r.f64s(nc)?, r.f64s(nc)?, r.f64s(nc)?);
    let phase = (0..nc).map(|_| r.phase()).collect::<Result<Vec<_>, _>>()?;
    Ok(State {
        time,
        q,
        qd,
        qdd,
        phase,
        q_star: r.f64s(n)?,
        qd_star: r.f64s(n)?,
        drive_force: r.f64s(n)?,
        damping_force: r.f64s(n)?,
        friction_force: r.f64s(nc)?,
        normal_load: r.f64s(n)?,
        lever_load: r.f64s(n)?,
        margin: r.f64s(nc)?,
        clearance_margin: r.f64s(n)?,
        reaction_force: r.vec3s(n)?,
        reaction_moment: r.vec3s(n)?,
        stick_count: (0..nc).map(|_| r.u64()).collect::<Result<_, _>>()?,
        stuck_time: r.f64s(nc)?,
        motor_torque: r.f64s(m)?,
        gear_torque: r.f64s(m)?,
        energy: Energy {
            kinetic: r.f64()?,
            potential: r.f64()?,
            spring: r.f64()?,
            drive_work: r.f64()?,
            friction_heat: r.f64()?,
            damping_heat: r.f64()?,
            rotor_kinetic: r.f64()?,
            motor_heat: r.f64()?,
        },
        end_point: r.vec3()?,
        end_point_rigid: r.vec3()?,
        steps: StepStatistics { accepted: r.u64()?, rejected: r.u64()?, last_h: r.f64()?, next_h: r.f64()? },
    })
}

#[derive(Default)]
struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, x: u8) {
        self.0.push(x);
    }
    fn u32(&mut self, x: u32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn u64(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.u64(x.to_bits());
    }
    fn f64s(&mut self, xs: &[f64]) {
        xs.iter().for_each(|x| self.f64(*x));
    }
}

/// Bounds-checked reading: running past the end is an error, never a panic.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, len: usize) -> Result<&[u8], String> {
        let end = self.at.checked_add(len).filter(|&e| e <= self.bytes.len()).ok_or("truncated payload")?;
        let taken = &self.bytes[self.at..end];
        self.at = end;
        Ok(taken)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn flag(&mut self) -> Result<bool, String> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(format!("flag byte {b} is neither 0 nor 1")),
        }
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, String> {
        (0..n).map(|_| self.f64()).collect()
    }
    fn vec3(&mut self) -> Result<Vec3, String> {
        Ok(Vec3::new(self.f64()?, self.f64()?, self.f64()?))
    }
    fn vec3s(&mut self, n: usize) -> Result<Vec<Vec3>, String> {
        (0..n).map(|_| self.vec3()).collect()
    }
    fn phase(&mut self) -> Result<Phase, String> {
        let tag = self.u8()?;
        let direction = i8::from_le_bytes([self.u8()?]);
        match (tag, direction) {
            (0, 0) => Ok(Phase::Prescribed),
            (1, 0) => Ok(Phase::Stuck),
            (2, d @ (-1 | 1)) => Ok(Phase::Slipping(d)),
            _ => Err(format!("invalid phase code ({tag}, {direction})")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Model;

    const HASH: u128 = 0x0123_4567_89ab_cdef_fedc_ba98_7654_3210;

    /// A snapshot whose every number is distinct, so that a field written in
    /// the wrong place cannot go unnoticed: of the reference arm with motor
    /// drives on joints 1 and 3 (6 coordinates).
    fn sample() -> Snapshot {
        let model = Model::reference_rrpr_motor();
        let n = model.nq();
        let mut state = State::new(&model);
        let mut x = 0.0;
        let mut next = || {
            x += 1.0;
            x * 0.1 + 1e-17 * x
        };
        state.time = next();
        for v in [
            &mut state.q,
            &mut state.qd,
            &mut state.qdd,
            &mut state.q_star,
            &mut state.qd_star,
            &mut state.drive_force,
            &mut state.damping_force,
            &mut state.friction_force,
            &mut state.normal_load,
            &mut state.lever_load,
            &mut state.stuck_time,
            &mut state.motor_torque,
            &mut state.gear_torque,
        ] {
            v.iter_mut().for_each(|e| *e = next());
        }
        state.margin = vec![f64::INFINITY, next(), -0.0, next(), next(), f64::INFINITY];
        state.stick_count = vec![3, 0, u64::MAX, 1, 7, 8];
        state.phase = vec![
            Phase::Slipping(-1),
            Phase::Prescribed,
            Phase::Slipping(1),
            Phase::Prescribed,
            Phase::Stuck,
            Phase::Slipping(-1),
        ];
        state
            .reaction_force
            .iter_mut()
            .chain(state.reaction_moment.iter_mut())
            .for_each(|v| *v = Vec3::new(next(), next(), next()));
        state.energy = Energy {
            kinetic: next(),
            potential: next(),
            spring: next(),
            drive_work: next(),
            friction_heat: next(),
            damping_heat: next(),
            rotor_kinetic: next(),
            motor_heat: next(),
        };
        state.end_point = Vec3::new(next(), next(), next());
        state.end_point_rigid = Vec3::new(next(), next(), next());
        state.clearance_margin = vec![f64::INFINITY, next(), -next(), f64::INFINITY];
        state.steps = StepStatistics { accepted: 123_456, rejected: 789, last_h: next(), next_h: next() };
        Snapshot {
            lifecycle: LifeCycle::StepFailed,
            start_time: -0.5,
            stop_time: Some(2.0),
            inputs: [vec![1.5; n], vec![-2.5; n], vec![f64::MIN_POSITIVE; n]],
            torques: [vec![0.125; n], vec![-3.5; n], vec![4.5; n]],
            use_start_values: true,
            q_start: vec![0.25; n],
            qd_start: vec![-0.75; n],
            theta_m_start: vec![12.5; n],
            omega_m_start: vec![-1.25; n],
            static_start: true,
            parameters: (0..7).map(|i| i as f64 * 3.5).collect(),
            state,
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let s = sample();
        let bytes = encode(&s, HASH);
        let back = decode(&bytes, HASH, 4, 2, 7).expect("decodes");
        assert_eq!(back, s);
        // Bit-exact, where == is not: -0.0 keeps its sign.
        assert!(back.state.margin[2].is_sign_negative());
        assert_eq!(encode(&back, HASH), bytes);
    }

    #[test]
    fn no_stop_time_round_trips() {
        let mut s = sample();
        s.stop_time = None;
        s.lifecycle = LifeCycle::InitializationMode;
        assert_eq!(decode(&encode(&s, HASH), HASH, 4, 2, 7).unwrap(), s);
    }

    #[test]
    fn every_single_byte_corruption_is_detected() {
        let bytes = encode(&sample(), HASH);
        for i in 0..bytes.len() {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut bad = bytes.clone();
                bad[i] ^= flip;
                assert!(decode(&bad, HASH, 4, 2, 7).is_err(), "flip {flip:#x} at byte {i} not detected");
            }
        }
    }

    #[test]
    fn every_truncation_and_padding_is_rejected() {
        let bytes = encode(&sample(), HASH);
        for len in 0..bytes.len() {
            assert!(decode(&bytes[..len], HASH, 4, 2, 7).is_err(), "prefix of {len} bytes accepted");
        }
        let mut padded = bytes.clone();
        padded.push(0);
        let err = decode(&padded, HASH, 4, 2, 7).unwrap_err();
        assert!(err.contains("truncated or padded"), "{err}");
    }

    #[test]
    fn foreign_buffers_are_rejected_with_the_reason() {
        let bytes = encode(&sample(), HASH);
        assert!(decode(&bytes, HASH ^ 1, 4, 2, 7).unwrap_err().contains("another model"));
        assert!(decode(&bytes, HASH, 5, 2, 7).unwrap_err().contains("4-joint"));
        assert!(decode(&bytes, HASH, 4, 1, 7).unwrap_err().contains("2 motor drives"));
        assert!(decode(&bytes, HASH, 4, 2, 8).unwrap_err().contains("parameter values"));
        assert!(decode(b"definitely not an FMU state, but long enough", HASH, 4, 2, 7).unwrap_err().contains("magic"));

        // A newer format version, with a valid checksum.
        let mut newer = bytes.clone();
        newer[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
        let body = newer.len() - 8;
        let checksum = fnv1a_64(&newer[..body]);
        newer[body..].copy_from_slice(&checksum.to_le_bytes());
        assert!(decode(&newer, HASH, 4, 2, 7).unwrap_err().contains(&format!("version {}", VERSION + 1)));
    }

    #[test]
    fn invalid_contents_with_a_valid_checksum_are_rejected() {
        let mut s = sample();
        s.state.phase[0] = Phase::Slipping(3);
        let bytes = encode(&s, HASH);
        assert!(decode(&bytes, HASH, 4, 2, 7).unwrap_err().contains("phase"));
    }

    mod properties {
        //! Arbitrary bytes, and arbitrary mutations of a valid FMU state
        //! (bit flips, truncation, extension, runs of zeros), never make the
        //! decoder panic: it returns a state that fits the model, or an error.
        use super::*;
        use proptest::prelude::*;

        fn decodes_or_refuses(bytes: &[u8]) {
            if let Ok(s) = decode(bytes, HASH, 4, 2, 7) {
                // Accepted bytes are a whole, well-formed state (the checksum
                // makes this all but impossible for mutated ones).
                assert_eq!(s.parameters.len(), 7);
                assert_eq!(s.state.nq(), 4);
                assert_eq!(encode(&s, HASH), bytes);
            }
        }

        proptest! {
            #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

            #[test]
            fn arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
                decodes_or_refuses(&bytes);
            }

            #[test]
            fn arbitrary_bytes_behind_a_valid_header(tail in proptest::collection::vec(any::<u8>(), 0..2048)) {
                let mut bytes = encode(&sample(), HASH)[..HEADER].to_vec();
                bytes.extend(tail);
                decodes_or_refuses(&bytes);
            }

            #[test]
            fn mutated_valid_states(
                flips in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..8), 0..8),
                cut in any::<prop::sample::Index>(),
                kind in 0u8..4,
                extra in proptest::collection::vec(any::<u8>(), 0..64),
            ) {
                let mut bytes = encode(&sample(), HASH);
                for (at, bit) in &flips {
                    let i = at.index(bytes.len());
                    bytes[i] ^= 1 << bit;
                }
                let at = cut.index(bytes.len());
                match kind {
                    0 => bytes.truncate(at),
                    1 => bytes.extend(&extra),
                    2 => bytes[at..].iter_mut().take(extra.len()).for_each(|b| *b = 0),
                    _ => {}
                }
                decodes_or_refuses(&bytes);
            }
        }
    }
}
