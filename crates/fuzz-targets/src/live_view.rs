//! What a live-view client sends once its handshake is done: WebSocket frames (read by
//! tungstenite as the view's server does, under the view's limits), each message decoded as a
//! Foxglove request.

use crate::Scratch;
use live_view::ws::{client_limits, protocol};
use std::io::{Read, Write};
use tungstenite::protocol::Role;
use tungstenite::{Message, WebSocket};

/// The client's bytes in; what the server writes back is dropped.
struct Wire<'a> {
    incoming: &'a [u8],
}

impl Read for Wire<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.incoming.read(buf)
    }
}

impl Write for Wire<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A client's frames after the handshake; accepted when every data message was a request
/// the view serves and the client closed.
pub fn messages(_scratch: &Scratch, data: &[u8]) -> bool {
    let (mut requests, mut unsupported) = (0, 0);
    let mut ws =
        WebSocket::from_raw_socket(Wire { incoming: data }, Role::Server, Some(client_limits()));
    let closed = loop {
        let request = match ws.read() {
            Ok(Message::Text(t)) => protocol::parse_text(t.as_str()),
            Ok(Message::Binary(b)) => protocol::parse_binary(&b),
            Ok(_) => continue,
            Err(e) => break matches!(e, tungstenite::Error::ConnectionClosed),
        };
        requests += 1;
        unsupported += usize::from(matches!(request, protocol::Request::Unsupported(_)));
    };
    closed && requests > 0 && unsupported == 0
}
