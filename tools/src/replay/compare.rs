//! A replayed period against the recorded one, field by field and bit for bit.

use videt_control::safety::SafetyState;
use videt_hal::DriveSample;
use videt_runtime::cycle::{CycleInputs, CycleRecord};

fn safety_text(s: SafetyState) -> String {
    match s.reason() {
        Some(r) => format!("{} ({})", s.as_str(), r.as_str()),
        None => s.as_str().to_string(),
    }
}

/// The first field in which `b` differs from `a` (floats compared bit for bit): (field, a, b).
pub fn first_difference(a: &CycleRecord, b: &CycleRecord) -> Option<(String, String, String)> {
    let diff = |name: String, x: String, y: String| Some((name, x, y));
    if a.cycle != b.cycle {
        return diff("cycle".into(), a.cycle.to_string(), b.cycle.to_string());
    }
    for (k, (va, vb)) in a.vectors().iter().zip(b.vectors()).enumerate() {
        for j in 0..3 {
            if va[j].to_bits() != vb[j].to_bits() {
                let (x, y) = floats(va[j], vb[j]);
                return diff(format!("{}[{j}]", CycleRecord::VECTOR_NAMES[k]), x, y);
            }
        }
    }
    let scalars = [
        ("contact_depth_m", a.contact_depth_m, b.contact_depth_m),
        ("force_scale", a.force_scale, b.force_scale),
    ];
    for (name, x, y) in scalars {
        if x.to_bits() != y.to_bits() {
            let (x, y) = floats(x, y);
            return diff(name.into(), x, y);
        }
    }
    if a.safety != b.safety {
        return diff(
            "safety".into(),
            safety_text(a.safety),
            safety_text(b.safety),
        );
    }
    let other = differ(
        || "in_contact".into(),
        a.in_contact,
        b.in_contact,
        ToString::to_string,
    )
    .or_else(|| {
        differ(
            || "surface_version".into(),
            a.surface_version,
            b.surface_version,
            ToString::to_string,
        )
    })
    .or_else(|| {
        differ(
            || "surface_stale".into(),
            a.surface_stale,
            b.surface_stale,
            ToString::to_string,
        )
    })
    .or_else(|| {
        differ(
            || "released_wire".into(),
            a.released_wire,
            b.released_wire,
            ToString::to_string,
        )
    });
    if other.is_some() {
        return other;
    }
    // The inputs are fed back; they come out different only if the replay does not read
    // them as the service did.
    first_input_difference(&a.inputs, &b.inputs)
}

/// Two floats as text for a difference report: scientific notation, with the bits when the
/// text alone does not tell them apart (`0` and `-0`, NaN payloads).
fn floats(x: f64, y: f64) -> (String, String) {
    let (tx, ty) = (format!("{x:e}"), format!("{y:e}"));
    if tx == ty {
        (
            format!("{tx} (bits {:#018x})", x.to_bits()),
            format!("{ty} (bits {:#018x})", y.to_bits()),
        )
    } else {
        (tx, ty)
    }
}

fn optional_ns(v: Option<u64>) -> String {
    v.map_or_else(|| "none".to_string(), |ns| format!("{ns} ns"))
}

fn ops_text(ops: &videt_runtime::cycle::CycleOps) -> String {
    let mut text = format!("{:?}", ops.as_slice());
    if ops.overflowed() {
        text.push_str(" (more not kept)");
    }
    text
}

/// `Some((name, x, y))` as text when `x` and `y` differ (formatted only then).
fn differ<T: PartialEq>(
    name: impl FnOnce() -> String,
    x: T,
    y: T,
    show: impl Fn(&T) -> String,
) -> Option<(String, String, String)> {
    (x != y).then(|| (name(), show(&x), show(&y)))
}

/// `Some((name, x, y))` when the floats differ bit for bit.
fn differ_bits(name: impl FnOnce() -> String, x: f64, y: f64) -> Option<(String, String, String)> {
    (x.to_bits() != y.to_bits()).then(|| {
        let (tx, ty) = floats(x, y);
        (name(), tx, ty)
    })
}

/// The first field in which the inputs `b` differ from `a`, named as in [`CycleInputs`]
/// (`drives[1].position_counts`, `tensions_read_n[0]`, `surface_frame_age_ns`, `ops`, ...;
/// floats compared bit for bit): (field, a, b).
pub fn first_input_difference(
    a: &CycleInputs,
    b: &CycleInputs,
) -> Option<(String, String, String)> {
    // Every field, by name: a field added to the inputs does not compile here until it is
    // compared.
    let CycleInputs {
        from_cycle,
        deadline_overrun,
        drives_read_ok,
        drives,
        tensions_read_ok,
        tensions_read_n,
        tensions_fresh,
        angles_read_ok,
        angles_rad,
        estop,
        torque_write,
        surface_live,
        surface_frame_age_ns,
        ops,
    } = a;
    let flag = |name: &'static str, x: bool, y: bool| {
        differ(|| name.to_string(), x, y, ToString::to_string)
    };
    let first = flag("from_cycle", *from_cycle, b.from_cycle)
        .or_else(|| flag("deadline_overrun", *deadline_overrun, b.deadline_overrun))
        .or_else(|| flag("drives_read_ok", *drives_read_ok, b.drives_read_ok));
    if first.is_some() {
        return first;
    }
    for (w, (x, y)) in drives.iter().zip(&b.drives).enumerate() {
        let DriveSample {
            position_counts,
            velocity_counts_per_s,
            state,
            error_code,
        } = x;
        let d = differ(
            || format!("drives[{w}].position_counts"),
            *position_counts,
            y.position_counts,
            ToString::to_string,
        )
        .or_else(|| {
            differ_bits(
                || format!("drives[{w}].velocity_counts_per_s"),
                *velocity_counts_per_s,
                y.velocity_counts_per_s,
            )
        })
        .or_else(|| {
            differ(
                || format!("drives[{w}].state"),
                *state,
                y.state,
                |s| format!("{s:?}"),
            )
        })
        .or_else(|| {
            differ(
                || format!("drives[{w}].error_code"),
                *error_code,
                y.error_code,
                |c| format!("{c:#06x}"),
            )
        });
        if d.is_some() {
            return d;
        }
    }
    if let Some(d) = flag("tensions_read_ok", *tensions_read_ok, b.tensions_read_ok) {
        return Some(d);
    }
    for w in 0..tensions_read_n.len() {
        let d = differ_bits(
            || format!("tensions_read_n[{w}]"),
            tensions_read_n[w],
            b.tensions_read_n[w],
        )
        .or_else(|| {
            differ(
                || format!("tensions_fresh[{w}]"),
                tensions_fresh[w],
                b.tensions_fresh[w],
                ToString::to_string,
            )
        });
        if d.is_some() {
            return d;
        }
    }
    if let Some(d) = flag("angles_read_ok", *angles_read_ok, b.angles_read_ok) {
        return Some(d);
    }
    for k in 0..angles_rad.len() {
        if let Some(d) = differ_bits(
            || format!("angles_rad[{k}]"),
            angles_rad[k],
            b.angles_rad[k],
        ) {
            return Some(d);
        }
    }
    differ(|| "estop".into(), *estop, b.estop, |e| format!("{e:?}"))
        .or_else(|| {
            differ(
                || "torque_write".into(),
                *torque_write,
                b.torque_write,
                |t| format!("{t:?}"),
            )
        })
        .or_else(|| flag("surface_live", *surface_live, b.surface_live))
        .or_else(|| {
            differ(
                || "surface_frame_age_ns".into(),
                *surface_frame_age_ns,
                b.surface_frame_age_ns,
                |v| optional_ns(*v),
            )
        })
        .or_else(|| differ(|| "ops".into(), *ops, b.ops, ops_text))
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_hal::DriveState;
    use videt_runtime::cycle::{CycleOp, CycleOps, EStopReading};

    fn inputs() -> CycleInputs {
        let mut i = CycleInputs {
            from_cycle: true,
            drives_read_ok: true,
            tensions_read_ok: true,
            tensions_read_n: [1.5, 2.5, 3.5],
            tensions_fresh: [true; 3],
            surface_live: true,
            ..CycleInputs::default()
        };
        for (w, d) in i.drives.iter_mut().enumerate() {
            d.position_counts = -1000 * w as i64;
            d.velocity_counts_per_s = 12.5 * w as f64;
            d.state = DriveState::Enabled;
        }
        i
    }

    #[test]
    fn inputs_differ_by_field_name_with_both_values() {
        let a = inputs();
        assert_eq!(first_input_difference(&a, &a), None);
        let diff = |change: &dyn Fn(&mut CycleInputs)| {
            let mut b = a;
            change(&mut b);
            first_input_difference(&a, &b).expect("a difference")
        };
        assert_eq!(
            diff(&|b| b.drives[1].position_counts += 1),
            (
                "drives[1].position_counts".into(),
                "-1000".into(),
                "-999".into()
            )
        );
        assert_eq!(
            diff(&|b| b.drives[2].state = DriveState::Fault).0,
            "drives[2].state"
        );
        assert_eq!(
            diff(&|b| b.drives[0].error_code = 0x2310),
            (
                "drives[0].error_code".into(),
                "0x0000".into(),
                "0x2310".into()
            )
        );
        assert_eq!(
            diff(&|b| b.surface_frame_age_ns = Some(7_250_000)),
            (
                "surface_frame_age_ns".into(),
                "none".into(),
                "7250000 ns".into()
            )
        );
        let (field, _, replayed) = diff(&|b| b.ops.push(CycleOp::ResetFaults));
        assert_eq!(field, "ops");
        assert!(replayed.contains("ResetFaults"), "{replayed}");
        let mut full = CycleOps::default();
        for _ in 0..=CycleOps::CAPACITY {
            full.push(CycleOp::RequestStop);
        }
        assert!(diff(&|b| b.ops = full).2.contains("more not kept"));
        // Floats bit for bit: -0 is not 0; NaNs with other payloads differ, and the bits say
        // so where the text cannot.
        let (field, recorded, replayed) = diff(&|b| b.tensions_read_n[0] = 1.5 + 1e-15);
        assert_eq!(field, "tensions_read_n[0]");
        assert_ne!(recorded, replayed);
        assert_eq!(
            diff(&|b| b.angles_rad[1] = -0.0),
            ("angles_rad[1]".into(), "0e0".into(), "-0e0".into())
        );
        let mut nan = a;
        nan.drives[1].velocity_counts_per_s = f64::NAN;
        let mut other_nan = nan;
        other_nan.drives[1].velocity_counts_per_s = f64::from_bits(f64::NAN.to_bits() | 1);
        let (field, recorded, replayed) = first_input_difference(&nan, &other_nan).unwrap();
        assert_eq!(field, "drives[1].velocity_counts_per_s");
        assert!(
            recorded.ends_with("(bits 0x7ff8000000000000)")
                && replayed.ends_with("(bits 0x7ff8000000000001)"),
            "{recorded} / {replayed}"
        );
        assert_eq!(first_input_difference(&nan, &nan), None);
        // The first field in the record's order is named.
        assert_eq!(
            diff(&|b| {
                b.tensions_fresh[2] = false;
                b.drives[2].position_counts = 5;
            })
            .0,
            "drives[2].position_counts"
        );
        assert_eq!(diff(&|b| b.estop = EStopReading::Failed).0, "estop");
        assert_eq!(diff(&|b| b.deadline_overrun = true).0, "deadline_overrun");
    }

    #[test]
    fn a_record_differing_in_an_input_names_it() {
        let a = CycleRecord {
            cycle: 7,
            inputs: inputs(),
            ..CycleRecord::default()
        };
        let mut b = a;
        b.inputs.tensions_read_n[2] = 4.0;
        let (field, recorded, replayed) = first_difference(&a, &b).unwrap();
        assert_eq!(
            (field.as_str(), recorded.as_str(), replayed.as_str()),
            ("tensions_read_n[2]", "3.5e0", "4e0")
        );
        // An output differing is named before any input.
        b.torque_nm[1] = 0.25;
        assert_eq!(first_difference(&a, &b).unwrap().0, "torque_nm[1]");
        assert_eq!(first_difference(&a, &a), None);
    }
}
