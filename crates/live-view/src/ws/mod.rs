//! The live view's WebSocket front: our own small server of the Foxglove WebSocket protocol
//! on `tungstenite` (blocking, a thread per client), because the view must decide who gets in
//! before the peer sees a byte — which the Foxglove SDK, owning its socket, cannot be told.
//!
//! Who gets in:
//! - a loopback connection only from the Unix user this process runs as (the kernel's owner
//!   of the client socket, [`peer::uid_of`]), refused before the handshake;
//! - when a token is set (the view listens beyond loopback), every connection must also carry
//!   it in the URL's query (`?token=…`; a browser can send it), compared in constant time;
//! - with a TLS identity ([`tls::Tls`]) every connection is TLS (`wss://`), the handshake
//!   done before the WebSocket's, so the token never travels in cleartext; a client pins the
//!   certificate by its fingerprint;
//! - a read-only front offers no parameters and no services.
//!
//! Both names of the protocol are served: `foxglove.websocket.v1` (its own, what the official
//! TypeScript client and the Foxglove app offer) and `foxglove.sdk.v1` (the SDK's).
//! Clients are bounded (at most [`MAX_CLIENTS`], frames of at most 1 MiB, a 5 s handshake);
//! a client that cannot keep up loses its own messages, never the view's loop.

pub mod peer;
pub mod protocol;
pub mod tls;

use protocol::{Parameter, Request, SUBPROTOCOLS};
use serde_json::json;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, Sender, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tls::Tls;
use tungstenite::handshake::server::{ErrorResponse, Request as HttpRequest, Response};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

/// Clients served at once.
pub const MAX_CLIENTS: usize = 16;
/// Messages waiting for one client before its newest are dropped.
const QUEUE: usize = 4096;

/// A channel the front advertises (JSON messages with a JSON schema).
#[derive(Debug, Clone)]
pub struct Channel {
    /// Channel id.
    pub id: u32,
    /// Topic.
    pub topic: String,
    /// Schema name.
    pub schema_name: String,
    /// JSON schema text.
    pub schema: String,
}

/// The one service the front may offer.
#[derive(Debug, Clone)]
pub struct Service {
    /// Service id.
    pub id: u32,
    /// Name.
    pub name: String,
    /// Type name.
    pub type_name: String,
    /// JSON schema of the request.
    pub request_schema: String,
    /// JSON schema of the response.
    pub response_schema: String,
}

/// What the front serves, where and to whom.
#[derive(Debug, Clone)]
pub struct FrontOptions {
    /// Server name shown to clients.
    pub name: String,
    /// Address to bind.
    pub host: String,
    /// Port (0: any free one).
    pub port: u16,
    /// Server metadata (`serverInfo`).
    pub metadata: BTreeMap<String, String>,
    /// Channels.
    pub channels: Vec<Channel>,
    /// The service, if any.
    pub service: Option<Service>,
    /// No parameters and no services.
    pub read_only: bool,
    /// A token every connection must carry (`?token=…`), if set.
    pub token: Option<String>,
    /// Serve TLS (`wss://`) with this identity, if set.
    pub tls: Option<Tls>,
}

/// A client's request for the view's loop, with where to answer.
pub enum Ask {
    /// Parameter values (names; empty: all).
    Get(Vec<String>, Reply),
    /// New parameter values.
    Set(Vec<Parameter>, Reply),
    /// The service was called.
    Call(ServiceReply),
}

/// Where a parameter request is answered.
pub struct Reply {
    out: SyncSender<Message>,
    id: Option<String>,
}

impl Reply {
    /// Answers with `params` (`parameterValues` with the request's id).
    pub fn respond(self, params: Vec<Parameter>) {
        let text = protocol::parameter_values(&params, self.id.as_deref());
        let _ = self.out.try_send(Message::text(text));
    }
}

/// Where a service call is answered.
pub struct ServiceReply {
    out: SyncSender<Message>,
    service: u32,
    call: u32,
    encoding: String,
}

impl ServiceReply {
    /// A successful response with `payload`.
    pub fn respond_ok(self, payload: Vec<u8>) {
        let frame =
            protocol::service_call_response(self.service, self.call, &self.encoding, &payload);
        let _ = self.out.try_send(Message::binary(frame));
    }

    /// A failure with `message`.
    pub fn respond_err(self, message: String) {
        let text = protocol::service_call_failure(self.service, self.call, &message);
        let _ = self.out.try_send(Message::text(text));
    }
}

/// A connected client as the publishers see it.
struct Client {
    id: u64,
    out: SyncSender<Message>,
    /// Channel id → the client's subscription id.
    subscriptions: HashMap<u32, u32>,
    /// Parameter names subscribed to (`None`: all).
    parameters: Option<HashSet<String>>,
    /// Whether the client subscribed to any parameter updates.
    parameters_subscribed: bool,
}

struct Shared {
    options: FrontOptions,
    clients: Mutex<Vec<Client>>,
    asks: Mutex<Sender<Ask>>,
    stop: AtomicBool,
    own_uid: Option<u32>,
    refused: AtomicU64,
    connected: AtomicUsize,
    next_id: AtomicU64,
}

/// The running front.
pub struct Front {
    shared: Arc<Shared>,
    port: u16,
    accept: Option<JoinHandle<()>>,
}

impl Front {
    /// Binds and starts accepting; clients' requests go to `asks`.
    pub fn start(options: FrontOptions, asks: Sender<Ask>) -> std::io::Result<Front> {
        let listener = TcpListener::bind((options.host.as_str(), options.port))?;
        listener.set_nonblocking(true)?;
        let port = listener.local_addr()?.port();
        let shared = Arc::new(Shared {
            options,
            clients: Mutex::new(Vec::new()),
            asks: Mutex::new(asks),
            stop: AtomicBool::new(false),
            own_uid: peer::own_uid(),
            refused: AtomicU64::new(0),
            connected: AtomicUsize::new(0),
            next_id: AtomicU64::new(1),
        });
        let s = shared.clone();
        let accept = std::thread::Builder::new()
            .name("view-accept".into())
            .spawn(move || accept_loop(&s, &listener))?;
        Ok(Front {
            shared,
            port,
            accept: Some(accept),
        })
    }

    /// The bound port.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Connections refused so far (another user, no token, too many clients).
    pub fn refused(&self) -> u64 {
        self.shared.refused.load(Ordering::Relaxed)
    }

    /// Sends `payload` on `channel` to every client subscribed to it.
    pub fn publish(&self, channel: u32, log_time_ns: u64, payload: &[u8]) {
        for c in self.shared.clients.lock().expect("clients").iter() {
            if let Some(&sub) = c.subscriptions.get(&channel) {
                let frame = protocol::message_data(sub, log_time_ns, payload);
                let _ = c.out.try_send(Message::binary(frame));
            }
        }
    }

    /// Sends changed parameter values to the clients subscribed to them.
    pub fn publish_parameters(&self, params: &[Parameter]) {
        if self.shared.options.read_only {
            return;
        }
        for c in self.shared.clients.lock().expect("clients").iter() {
            let wanted: Vec<Parameter> = params
                .iter()
                .filter(|p| {
                    c.parameters_subscribed
                        && c.parameters.as_ref().is_none_or(|n| n.contains(&p.name))
                })
                .cloned()
                .collect();
            if !wanted.is_empty() {
                let text = protocol::parameter_values(&wanted, None);
                let _ = c.out.try_send(Message::text(text));
            }
        }
    }

    /// A status message to every client (0 info, 1 warning, 2 error).
    pub fn publish_status(&self, level: u8, message: &str) {
        let text = protocol::status(level, message);
        for c in self.shared.clients.lock().expect("clients").iter() {
            let _ = c.out.try_send(Message::text(text.clone()));
        }
    }

    /// Stops accepting, closes every client (they take what was queued) and waits.
    pub fn stop(mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(a) = self.accept.take() {
            let _ = a.join();
        }
        for _ in 0..500 {
            if self.shared.connected.load(Ordering::Relaxed) == 0 {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

fn accept_loop(shared: &Arc<Shared>, listener: &TcpListener) {
    while !shared.stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, from)) => {
                if admitted(shared, &stream, from) {
                    shared.connected.fetch_add(1, Ordering::Relaxed);
                    let s = shared.clone();
                    let spawned = std::thread::Builder::new()
                        .name("view-client".into())
                        .spawn(move || {
                            serve_client(&s, stream);
                            s.connected.fetch_sub(1, Ordering::Relaxed);
                        });
                    if spawned.is_err() {
                        shared.connected.fetch_sub(1, Ordering::Relaxed);
                    }
                } else {
                    shared.refused.fetch_add(1, Ordering::Relaxed);
                    let _ = stream.shutdown(std::net::Shutdown::Both);
                }
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock || e.kind() == ErrorKind::Interrupted => {
                std::thread::sleep(Duration::from_millis(10))
            }
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
    }
}

/// Whether a connection from `from` may even start its handshake: from loopback, only this
/// process's user; from elsewhere, only when a token is required (checked in the handshake).
fn admitted(shared: &Shared, stream: &TcpStream, from: SocketAddr) -> bool {
    if shared.connected.load(Ordering::Relaxed) >= MAX_CLIENTS {
        return false;
    }
    if peer::is_loopback(from.ip()) {
        let Ok(local) = stream.local_addr() else {
            return false;
        };
        let owner = peer::uid_of(local, from);
        owner.is_some() && owner == shared.own_uid
    } else {
        shared.options.token.is_some()
    }
}

/// Constant-time equality of a presented and the expected token.
fn token_matches(presented: &str, expected: &str) -> bool {
    let (a, b) = (presented.as_bytes(), expected.as_bytes());
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The `token` query parameter of a request URI.
fn token_of(req: &HttpRequest) -> Option<&str> {
    req.uri()
        .query()?
        .split('&')
        .find_map(|kv| kv.strip_prefix("token="))
}

fn refusal(status: u16, why: &str) -> ErrorResponse {
    tungstenite::http::Response::builder()
        .status(status)
        .body(Some(why.to_owned()))
        .expect("a static response")
}

/// The handshake's check: the token (if required) and a subprotocol we serve. (The error
/// type is tungstenite's handshake callback's: its size is not ours to choose.)
#[allow(clippy::result_large_err)]
fn check_handshake(
    options: &FrontOptions,
    req: &HttpRequest,
    mut res: Response,
) -> Result<Response, ErrorResponse> {
    if let Some(expected) = &options.token {
        if !token_of(req).is_some_and(|t| token_matches(t, expected)) {
            return Err(refusal(
                401,
                "this live view needs its token: the ?token=… of the URL it printed",
            ));
        }
    }
    let offered: Vec<String> = req
        .headers()
        .get_all("sec-websocket-protocol")
        .iter()
        .flat_map(|h| h.to_str().unwrap_or_default().split(','))
        .map(|s| s.trim().to_owned())
        .collect();
    let Some(chosen) = offered.iter().find(|o| SUBPROTOCOLS.contains(&o.as_str())) else {
        return Err(refusal(
            400,
            "offer the subprotocol foxglove.websocket.v1 (or foxglove.sdk.v1)",
        ));
    };
    let value = tungstenite::http::HeaderValue::from_str(chosen).expect("a served name");
    res.headers_mut().insert("sec-websocket-protocol", value);
    Ok(res)
}

/// The first messages: server info, channels, the service.
fn hello(options: &FrontOptions) -> Vec<Message> {
    let capabilities: Vec<&str> = if options.read_only {
        vec![]
    } else {
        vec!["parameters", "parametersSubscribe", "services"]
    };
    let mut out = vec![Message::text(
        json!({
            "op": "serverInfo",
            "name": options.name,
            "capabilities": capabilities,
            "supportedEncodings": ["json"],
            "metadata": options.metadata,
            "sessionId": format!("{}", std::process::id()),
        })
        .to_string(),
    )];
    let channels: Vec<_> = options
        .channels
        .iter()
        .map(|c| {
            json!({
                "id": c.id, "topic": c.topic, "encoding": "json",
                "schemaName": c.schema_name, "schema": c.schema, "schemaEncoding": "jsonschema",
            })
        })
        .collect();
    out.push(Message::text(
        json!({"op": "advertise", "channels": channels}).to_string(),
    ));
    if let (Some(s), false) = (&options.service, options.read_only) {
        let schema = |name: String, text: &str| json!({"encoding": "json", "schemaName": name, "schemaEncoding": "jsonschema", "schema": text});
        out.push(Message::text(
            json!({"op": "advertiseServices", "services": [{
                "id": s.id, "name": s.name, "type": s.type_name,
                "request": schema(format!("{}Request", s.type_name), &s.request_schema),
                "response": schema(format!("{}Response", s.type_name), &s.response_schema),
                "requestSchema": s.request_schema, "responseSchema": s.response_schema,
            }]})
            .to_string(),
        ));
    }
    out
}

/// How long a client has for its TLS and WebSocket handshakes, each.
const HANDSHAKE: Duration = Duration::from_secs(5);

/// A client's byte stream: a TCP socket, or TLS over one.
trait Socket: std::io::Read + std::io::Write {
    /// The TCP socket under it.
    fn tcp(&self) -> &TcpStream;
}

impl Socket for TcpStream {
    fn tcp(&self) -> &TcpStream {
        self
    }
}

impl Socket for rustls::StreamOwned<rustls::ServerConnection, TcpStream> {
    fn tcp(&self) -> &TcpStream {
        &self.sock
    }
}

/// One client, from handshake to close: the TLS handshake first when the front has an
/// identity (within [`HANDSHAKE`]; a client that does not speak TLS fails it and sees nothing).
fn serve_client(shared: &Shared, stream: TcpStream) {
    let setup = stream.set_nonblocking(false).and_then(|()| {
        stream.set_read_timeout(Some(HANDSHAKE))?;
        stream.set_write_timeout(Some(HANDSHAKE))
    });
    if setup.is_err() {
        return;
    }
    let Some(tls) = &shared.options.tls else {
        return serve_socket(shared, stream);
    };
    let Ok(connection) = rustls::ServerConnection::new(tls.config.clone()) else {
        return;
    };
    let mut secure = rustls::StreamOwned::new(connection, stream);
    let deadline = Instant::now() + HANDSHAKE;
    while secure.conn.is_handshaking() {
        if Instant::now() > deadline || secure.conn.complete_io(&mut secure.sock).is_err() {
            return;
        }
    }
    serve_socket(shared, secure);
}

/// The limits a client's frames are read under: at most 1 MiB a message and a frame.
pub fn client_limits() -> WebSocketConfig {
    WebSocketConfig::default()
        .max_message_size(Some(1 << 20))
        .max_frame_size(Some(1 << 20))
}

/// One client over `stream`, from the WebSocket handshake to close.
fn serve_socket<S: Socket>(shared: &Shared, stream: S) {
    let options = &shared.options;
    let config = client_limits();
    #[allow(clippy::result_large_err)]
    let check = |req: &HttpRequest, res: Response| check_handshake(options, req, res);
    let accepted = tungstenite::accept_hdr_with_config(stream, check, Some(config));
    let Ok(mut ws) = accepted else {
        return;
    };
    if ws
        .get_ref()
        .tcp()
        .set_read_timeout(Some(Duration::from_millis(20)))
        .is_err()
    {
        return;
    }
    let (tx, rx) = sync_channel(QUEUE);
    let id = shared.next_id.fetch_add(1, Ordering::Relaxed);
    for m in hello(options) {
        let _ = tx.try_send(m);
    }
    shared.clients.lock().expect("clients").push(Client {
        id,
        out: tx.clone(),
        subscriptions: HashMap::new(),
        parameters: Some(HashSet::new()),
        parameters_subscribed: false,
    });
    client_loop(shared, &mut ws, id, &tx, &rx);
    shared
        .clients
        .lock()
        .expect("clients")
        .retain(|c| c.id != id);
}

fn client_loop<S: Socket>(
    shared: &Shared,
    ws: &mut WebSocket<S>,
    id: u64,
    tx: &SyncSender<Message>,
    rx: &Receiver<Message>,
) {
    loop {
        // What is queued goes out first, so a closing view still delivers it.
        while let Ok(m) = rx.try_recv() {
            if ws.write(m).is_err() {
                return;
            }
        }
        if matches!(ws.flush(), Err(e) if !would_block(&e)) {
            return;
        }
        if shared.stop.load(Ordering::Relaxed) {
            let _ = ws.close(None);
            let _ = ws.flush();
            return;
        }
        match ws.read() {
            Ok(Message::Text(t)) => handle(shared, id, tx, protocol::parse_text(t.as_str())),
            Ok(Message::Binary(b)) => handle(shared, id, tx, protocol::parse_binary(&b)),
            Ok(Message::Close(_)) => {
                let _ = ws.flush();
                return;
            }
            Ok(_) => {}
            Err(e) if would_block(&e) => {}
            Err(_) => return,
        }
    }
}

fn would_block(e: &tungstenite::Error) -> bool {
    matches!(e, tungstenite::Error::Io(io) if matches!(io.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut))
}

/// One request of client `id`.
fn handle(shared: &Shared, id: u64, tx: &SyncSender<Message>, request: Request) {
    let options = &shared.options;
    let ask = |a: Ask| {
        let _ = shared.asks.lock().expect("asks").send(a);
    };
    let refuse = |what: &str| {
        let _ = tx.try_send(Message::text(protocol::status(2, what)));
    };
    let with_client = |f: &mut dyn FnMut(&mut Client)| {
        if let Some(c) = shared
            .clients
            .lock()
            .expect("clients")
            .iter_mut()
            .find(|c| c.id == id)
        {
            f(c)
        }
    };
    match request {
        Request::Subscribe(pairs) => with_client(&mut |c| {
            for &(sub, channel) in &pairs {
                if options.channels.iter().any(|ch| ch.id == channel) {
                    c.subscriptions.insert(channel, sub);
                }
            }
        }),
        Request::Unsubscribe(subs) => {
            with_client(&mut |c| c.subscriptions.retain(|_, s| !subs.contains(s)))
        }
        _ if options.read_only => refuse("this live view is read-only: no parameters, no services"),
        Request::GetParameters(names, rid) => ask(Ask::Get(
            names,
            Reply {
                out: tx.clone(),
                id: rid,
            },
        )),
        Request::SetParameters(params, rid) => ask(Ask::Set(
            params,
            Reply {
                out: tx.clone(),
                id: rid,
            },
        )),
        Request::SubscribeParameters(names) => with_client(&mut |c| {
            c.parameters_subscribed = true;
            match (&mut c.parameters, names.is_empty()) {
                (p, true) => *p = None,
                (Some(set), false) => set.extend(names.iter().cloned()),
                (None, false) => {}
            }
        }),
        Request::UnsubscribeParameters(names) => with_client(&mut |c| {
            if names.is_empty() {
                c.parameters = Some(HashSet::new());
                c.parameters_subscribed = false;
            } else if let Some(set) = &mut c.parameters {
                set.retain(|n| !names.contains(n));
            }
        }),
        Request::CallService(service, call, encoding, _payload) => {
            let reply = ServiceReply {
                out: tx.clone(),
                service,
                call,
                encoding,
            };
            match &options.service {
                Some(s) if s.id == service => ask(Ask::Call(reply)),
                _ => reply.respond_err(format!("no service {service}")),
            }
        }
        Request::Unsupported(what) => refuse(&format!("not supported here: {what}")),
    }
}

/// A token for a view served beyond loopback: 128 random bits, hex.
pub fn new_token() -> std::io::Result<String> {
    use std::io::Read;
    let mut b = [0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut b)?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_compare_whole() {
        assert!(token_matches("abc", "abc"));
        assert!(!token_matches("abd", "abc") && !token_matches("ab", "abc"));
        assert_eq!(new_token().unwrap().len(), 32);
    }
}
