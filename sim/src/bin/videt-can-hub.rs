//! `videt-can-hub [ADDR] [--bitrate BPS]` — the hub of the cross-process userspace CAN bus:
//! forwards every frame an endpoint sends (UDP datagrams on the loopback interface) to every
//! other endpoint. Default address `127.0.0.1:47800`.
//!
//! With `--bitrate` the hub is the bus's wire: frames take their bit time at BPS bit/s, queue
//! while the bus is busy and win it by identifier; the bus load is printed every 5 s.

use std::time::Duration;

fn usage() -> std::process::ExitCode {
    eprintln!("usage: videt-can-hub [ADDR] [--bitrate BPS]   (BPS in 10000..=1000000)");
    std::process::ExitCode::from(2)
}

fn main() -> std::process::ExitCode {
    let mut addr = "127.0.0.1:47800".to_string();
    let mut bitrate = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bitrate" => match args.next().and_then(|v| v.parse::<u32>().ok()) {
                Some(b) if (10_000..=1_000_000).contains(&b) => bitrate = Some(b),
                _ => return usage(),
            },
            "-h" | "--help" => {
                usage();
                return std::process::ExitCode::SUCCESS;
            }
            s if !s.starts_with('-') => addr = s.to_string(),
            _ => return usage(),
        }
    }
    match bitrate {
        Some(b) => eprintln!("videt-can-hub: a {b} bit/s CAN bus on udp://{addr}"),
        None => eprintln!("videt-can-hub: forwarding CAN frames on udp://{addr} (no bit time)"),
    }
    let report = |s: &videt_sim::can_bus::BusStats| {
        let s = s.snapshot();
        eprintln!(
            "videt-can-hub: {} frames, load {:.1}%, wait mean {:.0} µs max {:.0} µs, {} lost to a full queue",
            s.frames,
            100.0 * s.load,
            s.mean_wait_us,
            s.max_wait_us,
            s.overflows
        );
    };
    match videt_sim::can_bus::udp::UdpHub::serve_forever(
        &addr,
        bitrate,
        Duration::from_secs(5),
        report,
    ) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("videt-can-hub: cannot bind {addr}: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
