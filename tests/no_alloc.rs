//! The control thread allocates and frees nothing: the real loop runs 10 000 periods on the
//! twin with surface snapshots arriving from a vision thread, the thimble state going back, the
//! status published and every period recorded by the telemetry writer — under a global allocator
//! that counts allocations made on the control thread. The live view runs beside it, sampling
//! its own copy of the status and serving it over the Foxglove WebSocket protocol.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use videt_config::Config;
use videt_control::{Contact, Surface, Vec3};
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::WireZero;
use videt_runtime::setup;
use videt_runtime::snapshot::snapshot_channel;
use videt_runtime::status::status_channel;
use videt_runtime::telemetry::{self, LogHeader};
use videt_runtime::thimble::thimble_channel;

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// A heap-backed surface (like the real mesh): a wall whose height comes from a table.
#[derive(Clone, Default)]
struct TableWall {
    z_by_column: Vec<f64>,
}

impl Surface for TableWall {
    fn contact(&self, p: &Vec3) -> Option<Contact> {
        if self.z_by_column.is_empty() {
            return None;
        }
        let i = ((p.x.max(0.0) * 100.0) as usize).min(self.z_by_column.len() - 1);
        let depth = p.z - self.z_by_column[i];
        (depth > 0.0).then(|| Contact {
            depth_m: depth,
            normal: Vec3::new(0.0, 0.0, -1.0),
        })
    }
}

#[test]
fn the_control_thread_allocates_and_frees_nothing() {
    let config = Config::default();
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 5);
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let (mut surface_writer, mut surface_reader) = snapshot_channel(TableWall {
        z_by_column: Vec::with_capacity(64),
    });
    let (thimble_publisher, mut thimble_reader) = thimble_channel();
    let (status_publisher, mut status_reader) = status_channel();
    let (live_publisher, live_status) = status_channel();
    let live = videt_viewers::live::LiveView::start(
        &videt_viewers::live::LiveSettings {
            host: "127.0.0.1".into(),
            port: 0,
            rate_hz: 30.0,
            client_backlog: 64,
            avoid_cpu: Some(1),
        },
        videt_viewers::topics::SceneSetup::new(&config, None),
        videt_viewers::live::LiveSources {
            status: live_status,
            surfaces: videt_runtime::telemetry::FeedRecording::default(),
            image: None,
            calibrations: None,
            config: config.clone(),
            session_log: None,
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (telemetry_producer, telemetry_writer) = telemetry::start(
        &dir.path().join("a.vlog"),
        LogHeader {
            rate_hz: 1000,
            start_unix_ns: 0,
        },
        1 << 15,
    )
    .unwrap();

    // Vision: keeps publishing rebuilt surfaces (allocating on its own thread) and reading the
    // thimble state.
    let done = Arc::new(AtomicBool::new(false));
    let vision_done = Arc::clone(&done);
    let vision = std::thread::spawn(move || {
        let mut published = 0u64;
        let mut seen_cycle = 0;
        while !vision_done.load(Ordering::Relaxed) {
            let wall_z = 0.33 + 0.001 * (published % 5) as f64;
            surface_writer.publish_with(|s| {
                // Sometimes rebuild from scratch (new allocation), sometimes in place.
                if published.is_multiple_of(3) {
                    *s = TableWall {
                        z_by_column: vec![wall_z; 50],
                    };
                } else {
                    s.z_by_column.clear();
                    s.z_by_column.resize(50, wall_z);
                }
            });
            published += 1;
            seen_cycle = seen_cycle.max(thimble_reader.latest().value.cycle);
            std::thread::yield_now();
        }
        (published, seen_cycle)
    });

    let control = std::thread::spawn(move || {
        let mut twin = scene.twin;
        start_hardware(&mut twin).unwrap();
        let settings = LoopSettings {
            rate_hz: 1000,
            duration_ns: Some(10_000_000_000),
            max_consecutive_overruns: 10,
        };
        let stop = AtomicBool::new(false);
        let mut stats = LoopStats::default();
        let mut observers = (
            status_publisher,
            thimble_publisher,
            (telemetry_producer, live_publisher),
        );
        let mut control = LoopControl::stop_flag(&stop);
        let (report, counts) = videt_testkit::count_allocations(|| {
            run_control_loop(
                &mut twin,
                &mut surface_reader,
                &mut cycle,
                &settings,
                &mut control,
                &mut observers,
                &mut stats,
            )
        });
        let last_version = surface_reader.latest().version;
        (report, counts, last_version, observers)
    });
    let (report, counts, last_version, observers) = control.join().unwrap();
    done.store(true, Ordering::Relaxed);
    let (published, seen_cycle) = vision.join().unwrap();
    drop(observers);
    let written = telemetry_writer
        .finish(telemetry::EndReason::DurationElapsed)
        .unwrap();
    let live = live.stop();

    assert!(report.cycles >= 10_000, "ran {} periods", report.cycles);
    assert!(
        published > 10 && last_version > 10,
        "surfaces flowed: {published} published, last seen {last_version}"
    );
    assert!(
        seen_cycle > 100,
        "the thimble state flowed back: {seen_cycle}"
    );
    assert!(status_reader.latest().record.cycle > 9_000);
    assert!(written > 9_000, "telemetry recorded {written} periods");
    // The twin runs on simulated time, faster than the wall clock the live view samples by.
    assert!(
        live.samples >= 3 && live.samples as f64 >= 0.5 * 30.0 * live.wall_s,
        "the live view sampled the loop at 30 Hz while it ran: {live:?}"
    );
    assert_eq!(
        counts,
        videt_testkit::AllocCounts::default(),
        "allocations and frees on the control thread"
    );
}

/// The control loop of every other device allocates nothing either: the planar prototype and
/// the one-wire device (its angle sensors read every period) run 3000 periods against the check
/// wall on their twins, status and telemetry observed.
#[test]
fn every_devices_control_loop_allocates_nothing() {
    fn run<const N: usize, D: videt_runtime::runtime_device::RuntimeDevice<N>>(device: D) {
        let config = Config::default();
        let scene = videt_assembly::twin_scene::wall_scene(
            &config,
            device,
            videt_assembly::twin_scene::thimble_start(&device),
            5,
        );
        let mut cycle = setup::control_cycle_for(&config, device, WireZero::default(), true);
        let (status_publisher, mut status_reader) = status_channel();
        let dir = tempfile::tempdir().unwrap();
        let (telemetry_producer, telemetry_writer) = telemetry::start(
            &dir.path().join("a.vlog"),
            LogHeader {
                rate_hz: 1000,
                start_unix_ns: 0,
            },
            1 << 13,
        )
        .unwrap();
        let mut twin = scene.twin;
        let mut wall = videt_runtime::snapshot::FixedSurface(scene.wall);
        start_hardware(&mut twin).unwrap();
        let settings = LoopSettings {
            rate_hz: 1000,
            duration_ns: Some(3_000_000_000),
            max_consecutive_overruns: 10,
        };
        let stop = AtomicBool::new(false);
        let mut stats = LoopStats::default();
        let mut observers = (status_publisher, telemetry_producer);
        let mut control = LoopControl::stop_flag(&stop);
        let (report, counts) = videt_testkit::count_allocations(|| {
            run_control_loop(
                &mut twin,
                &mut wall,
                &mut cycle,
                &settings,
                &mut control,
                &mut observers,
                &mut stats,
            )
        });
        drop(observers);
        telemetry_writer
            .finish(telemetry::EndReason::DurationElapsed)
            .unwrap();
        assert!(
            report.cycles >= 3_000,
            "{:?}: {} periods",
            D::KIND,
            report.cycles
        );
        let last = status_reader.latest().record;
        assert!(last.cycle > 2_900, "{:?}", D::KIND);
        assert_eq!(
            counts,
            videt_testkit::AllocCounts::default(),
            "{:?}: allocations and frees on the control thread",
            D::KIND
        );
    }
    run(videt_control::PlanarDevice::paper_prototype());
    run(videt_control::PolarDevice::at_origin());
}

/// A hand-over (auto-initialization through the control socket) adds nothing to the rendering
/// loop: the loop ramps out and returns without allocating; the procedure that then runs on the
/// control thread allocates only at its stage changes and its end, never per period.
#[test]
fn a_hand_over_allocates_nothing_and_a_procedure_nothing_per_period() {
    // The same initialisation at two winding speeds: the slower one runs many more periods
    // (and emits more progress events) through the same stages.
    let fast = hand_over_and_initialise(0.25);
    let slow = hand_over_and_initialise(0.125);
    for run in [&fast, &slow] {
        assert!(run.succeeded, "the procedure succeeded");
        assert!(run.handed_over);
        assert_eq!(
            run.hand_over_counts,
            videt_testkit::AllocCounts::default(),
            "the hand-over allocates nothing"
        );
        assert!(run.recalibrated);
        assert!(run.periods > 5_000, "{} periods", run.periods);
    }
    assert!(
        slow.periods as f64 > 1.3 * fast.periods as f64,
        "{} periods slow, {} fast",
        slow.periods,
        fast.periods
    );
    // Stage changes and the end allocate (messages, the result); periods and progress events
    // do not: the count does not grow with the number of periods.
    assert_eq!(
        slow.procedure_counts, fast.procedure_counts,
        "allocations on the control thread: {} periods {:?}, {} periods {:?}",
        slow.periods, slow.procedure_counts, fast.periods, fast.procedure_counts
    );
    assert!(fast.procedure_counts.allocations < 64, "{fast:?}");
}

/// What [`hand_over_and_initialise`] saw.
#[derive(Debug)]
struct ProcedureRun {
    succeeded: bool,
    handed_over: bool,
    hand_over_counts: videt_testkit::AllocCounts,
    recalibrated: bool,
    periods: u64,
    procedure_counts: videt_testkit::AllocCounts,
}

/// Renders a second on the twin, hands the control thread over to an initialisation run at
/// `wind_speed_m_s`, and counts the control thread's allocations in both parts.
fn hand_over_and_initialise(wind_speed_m_s: f64) -> ProcedureRun {
    use videt_runtime::control_loop::ControlCommand;
    use videt_service::init::remote::{
        procedure_channel, run_procedure, saved, ProcedureEvent, ProcedureKind, ProcedureSpec,
    };

    let mut config = Config::default();
    config.autoinit.wind_speed_m_s = wind_speed_m_s;
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 5);
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let wall = scene.wall;
    let dir = tempfile::tempdir().unwrap();
    let (port, mut handle) = procedure_channel(config.clone(), dir.path().join("c.toml"), true);
    let port = Arc::new(port);

    // The socket's side: takes the slot, submits, answers "saved" when the result comes.
    let client_port = Arc::clone(&port);
    let (submitted_tx, submitted_rx) = std::sync::mpsc::channel();
    let client = std::thread::spawn(move || {
        let mut session = client_port.begin().unwrap();
        session.submit(ProcedureSpec {
            kind: ProcedureKind::Initialize,
            yes: true,
            sim_seed: 3,
            sim_faults: Vec::new(),
            sim_new_wire_length_m: None,
        });
        submitted_tx.send(()).unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
        loop {
            assert!(std::time::Instant::now() < deadline, "no result");
            match session.next_event() {
                Some(ProcedureEvent::Finished(result)) => {
                    let ok = result.is_ok();
                    session.control().saved.store(
                        if ok { saved::SAVED } else { saved::NOT_SAVED },
                        Ordering::Release,
                    );
                    return ok;
                }
                Some(_) => {}
                None => std::thread::sleep(std::time::Duration::from_millis(1)),
            }
        }
    });
    submitted_rx.recv().unwrap();

    let control = std::thread::spawn(move || {
        let mut twin = scene.twin;
        start_hardware(&mut twin).unwrap();
        let settings = LoopSettings {
            rate_hz: 1000,
            duration_ns: Some(60_000_000_000),
            max_consecutive_overruns: 10,
        };
        let stop = AtomicBool::new(false);
        let (mut tx, mut rx) = rtrb::RingBuffer::new(4);
        let mut stats = LoopStats::default();
        let mut feed = videt_runtime::snapshot::FixedSurface(wall);
        let mut observer = ();
        // Render a second, then hand over.
        let mut first = LoopSettings {
            duration_ns: Some(1_000_000_000),
            ..settings
        };
        run_control_loop(
            &mut twin,
            &mut feed,
            &mut cycle,
            &first,
            &mut LoopControl::stop_flag(&stop),
            &mut observer,
            &mut stats,
        );
        start_hardware(&mut twin).unwrap();
        cycle.restart();
        tx.push(ControlCommand::HandOver).unwrap();
        first.duration_ns = settings.duration_ns;
        let mut loop_control = LoopControl {
            stop: &stop,
            commands: Some(&mut rx),
        };
        let (report, loop_counts) = videt_testkit::count_allocations(|| {
            run_control_loop(
                &mut twin,
                &mut feed,
                &mut cycle,
                &first,
                &mut loop_control,
                &mut observer,
                &mut stats,
            )
        });
        let mut counted = CountingObserver(0);
        let (end, procedure_counts) = videt_testkit::count_allocations(|| {
            run_procedure(
                &mut twin,
                &mut handle,
                &config,
                &mut counted,
                cycle.cycle_count(),
                cycle.wire_zero(),
                cycle.safety_state(),
            )
        });
        (
            report,
            loop_counts,
            end.recalibration.is_some(),
            counted.0,
            procedure_counts,
        )
    });
    let (report, hand_over_counts, recalibrated, periods, procedure_counts) =
        control.join().unwrap();
    eprintln!("procedure: {periods} periods, {procedure_counts:?} on the control thread");
    ProcedureRun {
        succeeded: client.join().unwrap(),
        handed_over: report.handed_over,
        hand_over_counts,
        recalibrated,
        periods,
        procedure_counts,
    }
}

/// Counts the periods it is shown.
struct CountingObserver(u64);

impl videt_runtime::control_loop::CycleObserver for CountingObserver {
    fn observe(
        &mut self,
        _record: &videt_runtime::cycle::CycleRecord,
        _window: &videt_runtime::control_loop::WindowStats,
    ) {
        self.0 += 1;
    }
}
