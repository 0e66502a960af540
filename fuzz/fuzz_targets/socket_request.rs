//! Fuzzes the control socket's request line: arbitrary bytes through `ClientRequest::parse` and
//! `Request::parse`, and through `socket::handle` (the answer the server sends, with a command
//! queue to the control thread) — what a local client's line reaches.
#![no_main]

use std::sync::{Mutex, OnceLock};

use libfuzzer_sys::fuzz_target;
use videt_runtime::control_loop::ControlCommand;
use videt_service::socket::{handle, write_line, ClientRequest, Request, ServerShared, StatusReport};
use videt_runtime::status::StatusSnapshot;

struct Server {
    shared: ServerShared,
    commands: Mutex<rtrb::Consumer<ControlCommand>>,
}

fn server() -> &'static Server {
    static SERVER: OnceLock<Server> = OnceLock::new();
    SERVER.get_or_init(|| {
        let (producer, consumer) = rtrb::RingBuffer::new(4);
        Server {
            shared: ServerShared {
                status: Mutex::new(StatusReport::from_snapshot(&StatusSnapshot::default(), 0)),
                commands: Mutex::new(producer),
                procedures: None,
                sim_faults: None,
                wires: 3,
            },
            commands: Mutex::new(consumer),
        }
    })
}

fuzz_target!(|data: &[u8]| {
    let client = ClientRequest::parse(data);
    let simple = Request::parse(data);
    if let Ok(r) = &simple {
        assert_eq!(
            client.as_ref().ok(),
            Some(&ClientRequest::Simple(r.clone()))
        );
    }
    let s = server();
    let response = handle(data, &s.shared);
    assert!(response.ok || response.error.is_some());
    // The reply goes back as one JSON line.
    let mut line = Vec::new();
    write_line(&mut line, &response).expect("a reply serialises");
    // Keep the queue from filling so that accepted commands keep reaching the push.
    let mut commands = s.commands.lock().expect("not poisoned");
    while commands.pop().is_ok() {}
});
