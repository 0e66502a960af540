//! A read-only server of the Foxglove WebSocket protocol (the `ws-protocol` specification,
//! subprotocol `foxglove.websocket.v1`, which Foxglove, Lichtblick and PlotJuggler speak; the
//! same messages are also offered as `foxglove.sdk.v1`, the Foxglove SDK's name for them).
//!
//! It is a sink of a [`foxglove::Context`]: the topics logged on the context (encoded by the
//! Foxglove SDK in its well-known schemas) are advertised to every client, and each message goes
//! to the clients subscribed to its channel. Clients only subscribe and unsubscribe: publishing,
//! services, parameters and assets are refused with a status message.
//!
//! Every client has its own thread and its own bounded queue. Logging a message only appends it
//! to the queues of the clients that want it (dropping the oldest when a queue is full), so a
//! slow or stalled client loses messages and delays nobody.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use base64::Engine;
use foxglove::{ChannelId, FoxgloveError, Metadata, RawChannel, Sink, SinkId};
use serde_json::json;
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::http::HeaderValue;
use tungstenite::{Message, WebSocket};

/// The subprotocols the server speaks, preferred first.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// Opcode of a binary message-data frame.
const MESSAGE_DATA: u8 = 0x01;

/// How long a client thread waits for work before looking at its socket again.
const IDLE_WAIT: Duration = Duration::from_millis(10);

/// Most clients served at once (more are refused at the handshake).
const MAX_CLIENTS: usize = 16;

/// The kernel's send buffer per client, bytes: small, so that a client that falls behind loses
/// its oldest messages from the server's queue instead of receiving seconds-old data that
/// waited in the kernel (at the default autotuning, several megabytes).
const SEND_BUFFER_BYTES: usize = 64 * 1024;

/// A channel as advertised.
#[derive(Debug, Clone)]
struct Advertised {
    topic: String,
    encoding: String,
    schema_name: String,
    schema_encoding: String,
    /// The schema: text as is, binary (protobuf descriptor sets) in base64.
    schema: String,
}

impl Advertised {
    fn of(channel: &RawChannel) -> Advertised {
        let (schema_name, schema_encoding, schema) = match channel.schema() {
            Some(s) => {
                // The protocol carries binary schemas in base64, text ones as they are.
                let text = match s.encoding.as_str() {
                    "protobuf" | "flatbuffer" => {
                        base64::engine::general_purpose::STANDARD.encode(&s.data)
                    }
                    _ => String::from_utf8_lossy(&s.data).into_owned(),
                };
                (s.name.clone(), s.encoding.clone(), text)
            }
            None => (String::new(), String::new(), String::new()),
        };
        Advertised {
            topic: channel.topic().to_string(),
            encoding: channel.message_encoding().to_string(),
            schema_name,
            schema_encoding,
            schema,
        }
    }

    fn json(&self, id: u64) -> serde_json::Value {
        json!({
            "id": id,
            "topic": self.topic,
            "encoding": self.encoding,
            "schemaName": self.schema_name,
            "schema": self.schema,
            "schemaEncoding": self.schema_encoding,
        })
    }
}

/// A message waiting for a client.
enum Outgoing {
    /// A JSON text message (protocol control: never dropped).
    Text(String),
    /// Message data: subscription, log time, payload.
    Data(u32, u64, Arc<[u8]>),
}

/// One connected client.
#[derive(Default)]
struct Client {
    /// Control messages and data, in order.
    queue: Mutex<ClientQueue>,
    wake: Condvar,
    /// Channel id → subscription id.
    subscriptions: Mutex<HashMap<u64, u32>>,
    closed: AtomicBool,
}

#[derive(Default)]
struct ClientQueue {
    items: VecDeque<Outgoing>,
    /// Data messages in `items`.
    data: usize,
    dropped: u64,
}

impl Client {
    fn push(&self, item: Outgoing, backlog: usize) {
        let mut q = self.queue.lock().unwrap_or_else(PoisonError::into_inner);
        if let Outgoing::Data(..) = item {
            if q.data >= backlog {
                // Drop the oldest message data; control messages stay.
                if let Some(i) = q.items.iter().position(|o| matches!(o, Outgoing::Data(..))) {
                    q.items.remove(i);
                    q.data -= 1;
                    q.dropped += 1;
                }
            }
            q.data += 1;
        }
        q.items.push_back(item);
        drop(q);
        self.wake.notify_one();
    }

    fn pop(&self) -> Option<Outgoing> {
        let mut q = self.queue.lock().unwrap_or_else(PoisonError::into_inner);
        let item = q.items.pop_front();
        if let Some(Outgoing::Data(..)) = item {
            q.data -= 1;
        }
        item
    }

    fn wait_for_work(&self) {
        let q = self.queue.lock().unwrap_or_else(PoisonError::into_inner);
        if q.items.is_empty() {
            let _ = self.wake.wait_timeout(q, IDLE_WAIT);
        }
    }
}

/// What the server and its sink share.
struct Shared {
    sink_id: SinkId,
    name: String,
    backlog: usize,
    channels: Mutex<BTreeMap<u64, Advertised>>,
    clients: Mutex<Vec<Arc<Client>>>,
    stop: AtomicBool,
    /// Messages dropped for slow clients, all clients together.
    dropped: AtomicU64,
    /// Clients served since the start.
    connections: AtomicU64,
}

impl Shared {
    /// Run `f` on every connected client (the ones gone are forgotten first).
    fn each_client(&self, mut f: impl FnMut(&Client)) {
        let mut clients = self.clients.lock().unwrap_or_else(PoisonError::into_inner);
        clients.retain(|c| !c.closed.load(Ordering::Acquire));
        clients.iter().for_each(|c| f(c));
    }
}

/// The server's end on the context: receives every logged message.
struct ServerSink(Arc<Shared>);

impl Sink for ServerSink {
    fn id(&self) -> SinkId {
        self.0.sink_id
    }

    fn log(
        &self,
        channel: &RawChannel,
        msg: &[u8],
        metadata: &Metadata,
    ) -> Result<(), FoxgloveError> {
        let id = u64::from(channel.id());
        let mut payload: Option<Arc<[u8]>> = None;
        self.0.each_client(|client| {
            let sub = client
                .subscriptions
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .get(&id)
                .copied();
            if let Some(sub) = sub {
                let data = payload.get_or_insert_with(|| Arc::from(msg)).clone();
                client.push(Outgoing::Data(sub, metadata.log_time, data), self.0.backlog);
            }
        });
        Ok(())
    }

    fn add_channels(&self, channels: &[&Arc<RawChannel>]) -> Option<Vec<ChannelId>> {
        let mut advertised = Vec::with_capacity(channels.len());
        {
            let mut known = self
                .0
                .channels
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            for c in channels {
                let a = Advertised::of(c);
                advertised.push(a.json(u64::from(c.id())));
                known.insert(u64::from(c.id()), a);
            }
        }
        let text = json!({"op": "advertise", "channels": advertised}).to_string();
        self.0
            .each_client(|client| client.push(Outgoing::Text(text.clone()), self.0.backlog));
        Some(channels.iter().map(|c| c.id()).collect())
    }

    fn remove_channel(&self, channel: &RawChannel) {
        let id = u64::from(channel.id());
        self.0
            .channels
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&id);
        let text = json!({"op": "unadvertise", "channelIds": [id]}).to_string();
        self.0.each_client(|client| {
            client
                .subscriptions
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .remove(&id);
            client.push(Outgoing::Text(text.clone()), self.0.backlog);
        });
    }
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The address could not be listened on.
    #[error("cannot listen on {address}: {source}")]
    Bind {
        /// `HOST:PORT` as given.
        address: String,
        /// Why.
        source: std::io::Error,
    },
    /// A thread could not be started.
    #[error("cannot start a thread: {0}")]
    Thread(std::io::Error),
}

/// A running server.
pub struct WsServer {
    shared: Arc<Shared>,
    address: SocketAddr,
    accept: Option<JoinHandle<()>>,
}

impl WsServer {
    /// Listen on `host:port` and serve the topics of `context`, at most `backlog` message data
    /// queued per client; the server's threads keep off `avoid_cpu` (the control thread's).
    pub fn start(
        context: &Arc<foxglove::Context>,
        host: &str,
        port: u16,
        backlog: usize,
        avoid_cpu: Option<usize>,
    ) -> Result<WsServer, ServeError> {
        let listener = TcpListener::bind((host, port)).map_err(|source| ServeError::Bind {
            address: format!("{host}:{port}"),
            source,
        })?;
        let address = listener.local_addr().map_err(|source| ServeError::Bind {
            address: format!("{host}:{port}"),
            source,
        })?;
        // Accepting polls, so that stopping never waits on a connection that does not come.
        listener
            .set_nonblocking(true)
            .map_err(|source| ServeError::Bind {
                address: format!("{host}:{port}"),
                source,
            })?;
        let shared = Arc::new(Shared {
            sink_id: SinkId::next(),
            name: "videtd".into(),
            backlog: backlog.max(1),
            channels: Mutex::default(),
            clients: Mutex::default(),
            stop: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
            connections: AtomicU64::new(0),
        });
        context.add_sink(Arc::new(ServerSink(Arc::clone(&shared))));
        let accept_shared = Arc::clone(&shared);
        let accept = std::thread::Builder::new()
            .name("videt-live-net".into())
            .spawn(move || {
                // The clients' threads inherit the mask.
                if let Some(cpu) = avoid_cpu {
                    videt_runtime::rt::keep_off_cpu(cpu);
                }
                accept_clients(&listener, &accept_shared)
            })
            .map_err(ServeError::Thread)?;
        Ok(WsServer {
            shared,
            address,
            accept: Some(accept),
        })
    }

    /// Where the server listens.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        let mut n = 0;
        self.shared.each_client(|_| n += 1);
        n
    }

    /// Message data dropped so far for clients that did not keep up.
    pub fn dropped(&self) -> u64 {
        let mut connected = 0;
        self.shared.each_client(|c| {
            connected += c
                .queue
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .dropped
        });
        self.shared.dropped.load(Ordering::Relaxed) + connected
    }

    /// Clients served since the start.
    pub fn connections(&self) -> u64 {
        self.shared.connections.load(Ordering::Relaxed)
    }

    /// Close every connection and stop listening.
    pub fn stop(mut self) {
        self.shut_down();
    }

    fn shut_down(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        if let Some(t) = self.accept.take() {
            let _ = t.join();
        }
    }
}

impl Drop for WsServer {
    fn drop(&mut self) {
        self.shut_down();
    }
}

fn accept_clients(listener: &TcpListener, shared: &Arc<Shared>) {
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    while !shared.stop.load(Ordering::Acquire) {
        match listener.accept() {
            Ok((stream, peer)) => {
                threads.retain(|t| !t.is_finished());
                if threads.len() >= MAX_CLIENTS {
                    tracing::warn!(%peer, "live view: {MAX_CLIENTS} clients already; refused");
                    continue;
                }
                let shared = Arc::clone(shared);
                match std::thread::Builder::new()
                    .name("videt-live-client".into())
                    .spawn(move || serve_client(stream, peer, &shared))
                {
                    Ok(t) => threads.push(t),
                    Err(e) => tracing::warn!(%peer, "live view: no thread for a client: {e}"),
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => std::thread::sleep(IDLE_WAIT),
            Err(e) => {
                tracing::warn!("live view: accepting a client failed: {e}");
                std::thread::sleep(IDLE_WAIT);
            }
        }
    }
    for t in threads {
        let _ = t.join();
    }
}

/// Accept the handshake when the client offers one of [`SUBPROTOCOLS`].
// The callback's result type (a refusal is a whole HTTP response) is tungstenite's.
#[allow(clippy::result_large_err)]
fn handshake(stream: TcpStream) -> Result<WebSocket<TcpStream>, String> {
    let callback = |request: &Request, mut response: Response| {
        let offered: Vec<String> = request
            .headers()
            .get_all("sec-websocket-protocol")
            .iter()
            .filter_map(|h| h.to_str().ok())
            .flat_map(|h| h.split(',').map(|p| p.trim().to_string()))
            .collect();
        match SUBPROTOCOLS
            .iter()
            .find(|p| offered.iter().any(|o| o == *p))
        {
            Some(chosen) => {
                response
                    .headers_mut()
                    .insert("sec-websocket-protocol", HeaderValue::from_static(chosen));
                Ok(response)
            }
            None => {
                let mut refusal = ErrorResponse::new(Some(format!(
                    "the Foxglove WebSocket protocol is served here: offer the subprotocol {}",
                    SUBPROTOCOLS.join(" or ")
                )));
                *refusal.status_mut() = tungstenite::http::StatusCode::BAD_REQUEST;
                Err(refusal)
            }
        }
    };
    tungstenite::accept_hdr(stream, callback).map_err(|e| e.to_string())
}

fn serve_client(stream: TcpStream, peer: SocketAddr, shared: &Arc<Shared>) {
    // The handshake blocks, briefly; then the socket is polled.
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
    let _ = stream.set_nodelay(true);
    let _ = socket2::SockRef::from(&stream).set_send_buffer_size(SEND_BUFFER_BYTES);
    let mut ws = match handshake(stream) {
        Ok(ws) => ws,
        Err(e) => {
            tracing::info!(%peer, "live view: handshake refused: {e}");
            return;
        }
    };
    if ws.get_ref().set_nonblocking(true).is_err() {
        return;
    }
    let client = Arc::new(Client::default());
    shared.connections.fetch_add(1, Ordering::Relaxed);
    tracing::info!(%peer, "live view: client connected");
    // The greeting and the channels first, then the client is visible to the sink.
    client.push(Outgoing::Text(server_info(shared)), shared.backlog);
    {
        let channels = shared
            .channels
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let list: Vec<_> = channels.iter().map(|(id, a)| a.json(*id)).collect();
        client.push(
            Outgoing::Text(json!({"op": "advertise", "channels": list}).to_string()),
            shared.backlog,
        );
    }
    shared
        .clients
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .push(Arc::clone(&client));
    let why = client_loop(&mut ws, &client, shared);
    client.closed.store(true, Ordering::Release);
    let dropped = client
        .queue
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .dropped;
    shared.dropped.fetch_add(dropped, Ordering::Relaxed);
    let _ = ws.close(None);
    let _ = ws.flush();
    tracing::info!(%peer, dropped, "live view: client gone ({why})");
}

/// Serve one client until it leaves, fails or the server stops; why it ended.
fn client_loop(ws: &mut WebSocket<TcpStream>, client: &Client, shared: &Shared) -> String {
    loop {
        if shared.stop.load(Ordering::Acquire) {
            return "the service stops".into();
        }
        // What the client says.
        loop {
            match ws.read() {
                Ok(Message::Text(text)) => {
                    if let Some(reply) = handle_request(text.as_str(), client, shared) {
                        client.push(Outgoing::Text(reply), shared.backlog);
                    }
                }
                Ok(Message::Binary(_)) => client.push(
                    Outgoing::Text(status(
                        2,
                        "this live view is read-only: clients do not publish",
                    )),
                    shared.backlog,
                ),
                Ok(Message::Close(_)) => return "closed by the client".into(),
                Ok(_) => {}
                Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) => return e.to_string(),
            }
        }
        // What goes to the client: only once the socket took everything before.
        let mut writable = match ws.flush() {
            Ok(()) => true,
            Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => false,
            Err(e) => return e.to_string(),
        };
        let mut sent = false;
        while writable {
            let Some(item) = client.pop() else { break };
            let message = match item {
                Outgoing::Text(t) => Message::text(t),
                Outgoing::Data(sub, time_ns, payload) => {
                    let mut frame = Vec::with_capacity(13 + payload.len());
                    frame.push(MESSAGE_DATA);
                    frame.extend_from_slice(&sub.to_le_bytes());
                    frame.extend_from_slice(&time_ns.to_le_bytes());
                    frame.extend_from_slice(&payload);
                    Message::binary(frame)
                }
            };
            sent = true;
            match ws.write(message) {
                Ok(()) => {}
                // Buffered by the socket layer: the rest waits for the next flush.
                Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => {
                    writable = false
                }
                Err(e) => return e.to_string(),
            }
        }
        if sent {
            match ws.flush() {
                Ok(()) => {}
                Err(tungstenite::Error::Io(e)) if e.kind() == ErrorKind::WouldBlock => {}
                Err(e) => return e.to_string(),
            }
        }
        if !writable {
            // The socket is full (a slow or stalled client): look again later; its queue keeps
            // the newest messages meanwhile.
            std::thread::sleep(IDLE_WAIT);
        } else if !sent {
            client.wait_for_work();
        }
    }
}

fn server_info(shared: &Shared) -> String {
    json!({
        "op": "serverInfo",
        "name": shared.name,
        // Read-only: no clientPublish, services, parameters, assets or connection graph.
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {"videt_version": env!("CARGO_PKG_VERSION")},
        "sessionId": format!("{}", std::process::id()),
    })
    .to_string()
}

fn status(level: u8, message: &str) -> String {
    json!({"op": "status", "level": level, "message": message}).to_string()
}

/// Act on a client's request; the reply, if any.
fn handle_request(text: &str, client: &Client, shared: &Shared) -> Option<String> {
    let request: serde_json::Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return Some(status(2, &format!("not a JSON request: {e}"))),
    };
    let op = request.get("op").and_then(|o| o.as_str()).unwrap_or("");
    match op {
        "subscribe" => {
            let known = shared
                .channels
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            let mut subs = client
                .subscriptions
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            let mut unknown = Vec::new();
            for s in request
                .get("subscriptions")
                .and_then(|s| s.as_array())
                .into_iter()
                .flatten()
            {
                let (Some(id), Some(channel)) = (
                    s.get("id").and_then(|v| v.as_u64()),
                    s.get("channelId").and_then(|v| v.as_u64()),
                ) else {
                    return Some(status(
                        2,
                        "subscribe: each subscription needs an id and a channelId",
                    ));
                };
                match (known.contains_key(&channel), u32::try_from(id)) {
                    (true, Ok(id)) => {
                        subs.insert(channel, id);
                    }
                    _ => unknown.push(channel),
                }
            }
            (!unknown.is_empty()).then(|| status(1, &format!("subscribe: no channel {unknown:?}")))
        }
        "unsubscribe" => {
            let ids: Vec<u64> = request
                .get("subscriptionIds")
                .and_then(|s| s.as_array())
                .into_iter()
                .flatten()
                .filter_map(|v| v.as_u64())
                .collect();
            client
                .subscriptions
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .retain(|_, sub| !ids.contains(&u64::from(*sub)));
            None
        }
        "" => Some(status(2, "a request without an op")),
        other => Some(status(
            2,
            &format!("this live view is read-only: {other:?} is not supported"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_queue_drops_its_oldest_data_and_keeps_control_messages() {
        let client = Client::default();
        client.push(Outgoing::Text("hello".into()), 2);
        for i in 0..5u64 {
            client.push(Outgoing::Data(1, i, Arc::from(&[i as u8][..])), 2);
        }
        let mut kept = Vec::new();
        while let Some(item) = client.pop() {
            kept.push(match item {
                Outgoing::Text(t) => t,
                Outgoing::Data(_, t, _) => t.to_string(),
            });
        }
        assert_eq!(kept, ["hello", "3", "4"]);
        assert_eq!(client.queue.lock().unwrap().dropped, 3);
    }

    #[test]
    fn requests_other_than_subscriptions_are_refused_by_name() {
        let shared = Shared {
            sink_id: SinkId::next(),
            name: "t".into(),
            backlog: 4,
            channels: Mutex::new(BTreeMap::from([(
                7,
                Advertised {
                    topic: "/a".into(),
                    encoding: "json".into(),
                    schema_name: String::new(),
                    schema_encoding: String::new(),
                    schema: String::new(),
                },
            )])),
            clients: Mutex::default(),
            stop: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
            connections: AtomicU64::new(0),
        };
        let client = Client::default();
        let sub =
            r#"{"op":"subscribe","subscriptions":[{"id":3,"channelId":7},{"id":4,"channelId":9}]}"#;
        let reply = handle_request(sub, &client, &shared).unwrap();
        assert!(reply.contains("no channel [9]"), "{reply}");
        assert_eq!(client.subscriptions.lock().unwrap().get(&7), Some(&3));
        assert!(handle_request(
            r#"{"op":"unsubscribe","subscriptionIds":[3]}"#,
            &client,
            &shared
        )
        .is_none());
        assert!(client.subscriptions.lock().unwrap().is_empty());
        for op in ["advertise", "callService", "setParameters", "fetchAsset"] {
            let reply = handle_request(&format!(r#"{{"op":"{op}"}}"#), &client, &shared).unwrap();
            assert!(reply.contains("read-only") && reply.contains(op), "{reply}");
        }
        assert!(handle_request("not json", &client, &shared)
            .unwrap()
            .contains("JSON"));
    }
}
