//! `videt-can-hub [ADDR]` — the hub of the cross-process userspace CAN bus: forwards every frame
//! an endpoint sends (UDP datagrams on the loopback interface) to every other endpoint.
//! Default address `127.0.0.1:47800`.

fn main() -> std::process::ExitCode {
    let addr = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "127.0.0.1:47800".to_string());
    eprintln!("videt-can-hub: forwarding CAN frames on udp://{addr}");
    match videt_sim::can_bus::udp::UdpHub::serve_forever(&addr) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("videt-can-hub: cannot bind {addr}: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
