//! The live view: a running simulation's topics served over the Foxglove WebSocket protocol
//! (Foxglove's own SDK, `foxglove`), so Foxglove or Lichtblick shows the arms as they move.
//!
//! [`Live`] is a message sink beside the MCAP file: the recorder ([`crate::Recorder`]) adds the
//! same channels (schema, topic, encoding) to both and writes each message to both, so the live
//! topics are the recording's, byte for byte. A later sink (the ROS 2 twin) takes the same calls.
//! Each server has its own Foxglove context: two simulations in one process do not see each
//! other's channels. Logging never blocks the simulation: a slow client's queue drops its oldest
//! messages (the SDK's backlog).

use crate::error::{Result, SimError};
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle};
use std::sync::Arc;

/// Where to listen.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LiveOptions {
    /// Interface to bind: 127.0.0.1 unless told otherwise (the protocol has no authentication).
    pub host: String,
    /// TCP port; 0 picks a free one ([`Live::port`] says which).
    pub port: u16,
}

impl LiveOptions {
    /// Foxglove's default port.
    pub const DEFAULT_PORT: u16 = 8765;

    /// `HOST:PORT`, `PORT` or `HOST` (the default port); empty: 127.0.0.1 on the default port.
    pub fn parse(s: &str) -> std::result::Result<LiveOptions, String> {
        let s = s.trim();
        let bad = |why: &str| format!("--live `{s}`: {why} (expected HOST:PORT, PORT or HOST)");
        let (host, port) = match s.rsplit_once(':') {
            Some((h, p)) => (h, Some(p)),
            None if !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) => ("", Some(s)),
            None => (s, None),
        };
        let port = match port {
            Some(p) => p.parse::<u16>().map_err(|_| bad("the port is not a number in 0..65535"))?,
            None => Self::DEFAULT_PORT,
        };
        let host = if host.is_empty() { "127.0.0.1" } else { host };
        if host.contains(char::is_whitespace) {
            return Err(bad("the host has a space"));
        }
        Ok(LiveOptions { host: host.into(), port })
    }
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions { host: "127.0.0.1".into(), port: Self::DEFAULT_PORT }
    }
}

/// A running Foxglove WebSocket server and the channels advertised on it.
pub struct Live {
    context: Arc<Context>,
    server: Option<WebSocketServerHandle>,
    channels: Vec<Arc<RawChannel>>,
    host: String,
    port: u16,
}

impl std::fmt::Debug for Live {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Live(ws://{}:{}, {} channels)", self.host, self.port, self.channels.len())
    }
}

impl Live {
    /// Start serving (no channel yet); fails with the address when it cannot bind.
    pub fn serve(options: &LiveOptions, name: &str) -> Result<Live> {
        let context = Context::new();
        let server = WebSocketServer::new()
            .name(name)
            .bind(options.host.clone(), options.port)
            .context(&context)
            .start_blocking()
            .map_err(|e| SimError::Build(format!("--live {}:{}: cannot serve: {e}", options.host, options.port)))?;
        let port = server.port();
        Ok(Live { context, server: Some(server), channels: Vec::new(), host: options.host.clone(), port })
    }

    /// The port served (the one chosen when asked for 0).
    pub fn port(&self) -> u16 {
        self.port
    }

    /// `ws://HOST:PORT`.
    pub fn url(&self) -> String {
        format!("ws://{}:{}", self.host, self.port)
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, |s| s.client_count())
    }

    /// Advertise a channel; its index for [`Live::log`].
    pub fn add_channel(&mut self, topic: &str, schema: Schema, message_encoding: &str) -> Result<usize> {
        let channel = ChannelBuilder::new(topic)
            .schema(schema)
            .message_encoding(message_encoding)
            .context(&self.context)
            .build_raw()
            .map_err(|e| SimError::Build(format!("live channel {topic}: {e}")))?;
        self.channels.push(channel);
        Ok(self.channels.len() - 1)
    }

    /// Whether a client subscribes to channel `channel` now.
    pub fn subscribed(&self, channel: usize) -> bool {
        self.channels.get(channel).is_some_and(|c| c.has_sinks())
    }

    /// Send one message on channel `channel` stamped `t_ns` (ns of simulated time); nothing is
    /// encoded or copied when no client subscribes.
    pub fn log(&self, channel: usize, t_ns: u64, data: &[u8]) {
        if let Some(c) = self.channels.get(channel) {
            if c.has_sinks() {
                c.log_with_meta(data, PartialMetadata { log_time: Some(t_ns) });
            }
        }
    }

    /// Close the connections and stop serving (waits for the server's tasks).
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        for c in self.channels.drain(..) {
            c.close();
        }
        if let Some(s) = self.server.take() {
            s.stop().wait_blocking();
        }
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_with_the_defaults_filled_in() {
        let p = |s: &str| LiveOptions::parse(s);
        assert_eq!(p("").unwrap(), LiveOptions::default());
        assert_eq!(p("9000").unwrap(), LiveOptions { host: "127.0.0.1".into(), port: 9000 });
        assert_eq!(p("0.0.0.0:8000").unwrap(), LiveOptions { host: "0.0.0.0".into(), port: 8000 });
        assert_eq!(p("robot.local").unwrap(), LiveOptions { host: "robot.local".into(), port: 8765 });
        assert_eq!(p(":0").unwrap(), LiveOptions { host: "127.0.0.1".into(), port: 0 });
        assert!(p("host:70000").unwrap_err().contains("0..65535"));
    }
}
