//! The ROS 2 side of a served simulation: a DDS participant (RustDDS, pure Rust: no ROS
//! installation) that publishes the recorder's CRTK topics as the dVRK console does and takes
//! commands. It is a sink of the recorder beside the MCAP file and the Foxglove view
//! ([`crate::Recorder::open`]): the same channels, the same CDR bytes ([`raw`]).
//!
//! Network: loopback only unless told otherwise ([`Ros2Options::networks`]); RustDDS's default
//! would announce on every interface. QoS as the dVRK uses it: reliable, volatile, keep last 10.
//! The node is not listed by `ros2 node list` (no `ros_discovery_info`); its topics are, through
//! DDS discovery.

pub mod raw;

use crate::error::{Result, SimError};
use crate::recording::ros_msgs;
use raw::{dds_topic_name, dds_type_name, RawAdapter, RawCdr};
use rustdds::no_key::{DataWriter, SimpleDataReader};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{DomainParticipant, DomainParticipantBuilder, QosPolicies, QosPolicyBuilder, TopicKind};
use std::net::IpAddr;

/// Where and as whom to serve.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Options {
    /// The DDS domain (0..=232; `ROS_DOMAIN_ID`).
    pub domain: u16,
    /// Interfaces to announce and listen on besides loopback (which is always one): loopback
    /// only when empty.
    pub networks: Vec<IpAddr>,
    /// The logger name on `/rosout`.
    pub node: String,
}

impl Ros2Options {
    /// The largest domain id ROS 2 allows (the UDP ports of higher ones collide).
    pub const MAX_DOMAIN: u16 = 232;

    /// The domain `ROS_DOMAIN_ID` names (0 when unset); an error naming the value otherwise.
    pub fn domain_from_env() -> Result<u16> {
        match std::env::var("ROS_DOMAIN_ID") {
            Err(_) => Ok(0),
            Ok(s) if s.trim().is_empty() => Ok(0),
            Ok(s) => s.trim().parse::<u16>().ok().filter(|d| *d <= Self::MAX_DOMAIN).ok_or_else(|| SimError::Build(format!("ROS_DOMAIN_ID `{s}`: not a domain id in 0..={}", Self::MAX_DOMAIN))),
        }
    }
}

/// Reliable QoS (a writer blocks at most 100 ms) with `durability`, keeping the last `depth`.
fn reliable_qos(durability: Durability, depth: i32) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable { max_blocking_time: rustdds::Duration::from_millis(100) })
        .durability(durability)
        .history(History::KeepLast { depth })
        .build()
}

/// The dVRK's QoS: reliable, volatile, keep last 10.
fn dvrk_qos() -> QosPolicies {
    reliable_qos(Durability::Volatile, 10)
}

/// `/rosout`'s QoS in ROS 2: reliable, transient local, keep last 1000.
fn rosout_qos() -> QosPolicies {
    reliable_qos(Durability::TransientLocal, 1000)
}

/// The `/rosout` writer's QoS: [`rosout_qos`], but a write never waits (no blocking time: a
/// full send window refuses the line at once), for it is written from the real-time loop.
fn rosout_writer_qos() -> QosPolicies {
    rosout_qos().modify_by(&QosPolicyBuilder::new().reliability(Reliability::Reliable { max_blocking_time: rustdds::Duration::ZERO }).build())
}

/// The QoS a published topic takes (jhu-dvrk/dvrk_simulator_base's contract, `ros_qos.py`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopicQos {
    /// A stream: reliable, volatile, keep last 10.
    Stream,
    /// An event (`operating_state`, `state`): reliable, transient local, keep last 10, so a
    /// client that joins later gets the last ones at once.
    Event,
    /// Latched (`tool_type`): reliable, transient local, keep last 1.
    Latched,
    /// A warning stream (`warning`, `info`, `error`): a stream whose writes never wait (written
    /// from the real-time loop; a full send window drops the line).
    Warning,
}

impl TopicQos {
    fn policies(self) -> QosPolicies {
        match self {
            TopicQos::Stream => dvrk_qos(),
            TopicQos::Event => reliable_qos(Durability::TransientLocal, 10),
            TopicQos::Latched => reliable_qos(Durability::TransientLocal, 1),
            TopicQos::Warning => dvrk_qos().modify_by(&QosPolicyBuilder::new().reliability(Reliability::Reliable { max_blocking_time: rustdds::Duration::ZERO }).build()),
        }
    }
}

/// A subscription to one command topic.
struct Command {
    topic: String,
    reader: SimpleDataReader<RawCdr, RawAdapter>,
}

/// A running DDS participant with its writers (one per recorder channel that ROS 2 carries)
/// and command readers.
pub struct Ros2 {
    participant: DomainParticipant,
    publisher: rustdds::Publisher,
    subscriber: rustdds::Subscriber,
    qos: QosPolicies,
    writers: Vec<Option<DataWriter<RawCdr, RawAdapter>>>,
    commands: Vec<Command>,
    rosout: DataWriter<RawCdr, RawAdapter>,
    node: String,
    domain: u16,
}

impl std::fmt::Debug for Ros2 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Ros2(domain {}, {} topics, {} commands)", self.domain, self.writers.iter().flatten().count(), self.commands.len())
    }
}

fn dds_error(what: &str, e: impl std::fmt::Display) -> SimError {
    SimError::Build(format!("ROS 2: {what}: {e}"))
}

impl Ros2 {
    /// Join the domain (loopback only unless `options.networks` names interfaces).
    pub fn start(options: &Ros2Options) -> Result<Ros2> {
        if options.domain > Ros2Options::MAX_DOMAIN {
            return Err(SimError::value("ROS 2 domain (--domain)", options.domain as f64, format!("must be in 0..={}", Ros2Options::MAX_DOMAIN)));
        }
        // An address no interface of this machine has would be accepted by RustDDS and the twin
        // would be unreachable there without a word: binding a socket to it is the check.
        for n in &options.networks {
            if let Err(e) = std::net::UdpSocket::bind((*n, 0)) {
                return Err(SimError::Build(format!("ROS 2 network (--network) {n}: no interface of this machine has that address ({e})")));
            }
        }
        let mut networks = options.networks.clone();
        if !networks.iter().any(|n| n.is_loopback()) {
            networks.push(IpAddr::from([127, 0, 0, 1]));
        }
        let participant = DomainParticipantBuilder::new(options.domain).with_only_networks(networks).build().map_err(|e| dds_error(&format!("domain {}", options.domain), e))?;
        let qos = dvrk_qos();
        let publisher = participant.create_publisher(&qos).map_err(|e| dds_error("publisher", e))?;
        let subscriber = participant.create_subscriber(&qos).map_err(|e| dds_error("subscriber", e))?;
        let topic = participant
            .create_topic(dds_topic_name("/rosout"), dds_type_name("rcl_interfaces/msg/Log").expect("a ROS type"), &rosout_qos(), TopicKind::NoKey)
            .map_err(|e| dds_error("/rosout", e))?;
        let rosout = publisher.create_datawriter_no_key::<RawCdr, RawAdapter>(&topic, Some(rosout_writer_qos())).map_err(|e| dds_error("/rosout", e))?;
        Ok(Ros2 { participant, publisher, subscriber, qos, writers: Vec::new(), commands: Vec::new(), rosout, node: options.node.clone(), domain: options.domain })
    }

    /// The domain joined.
    pub fn domain(&self) -> u16 {
        self.domain
    }

    /// Add a recorder channel: published when it carries a ROS 2 message in CDR
    /// (`schema_encoding` `ros2msg`, `encoding` `cdr`), skipped otherwise (Foxglove's own
    /// messages). Its index for [`Ros2::log`].
    pub fn add_channel(&mut self, topic: &str, schema_name: &str, schema_encoding: &str, encoding: &str) -> Result<usize> {
        self.add_channel_qos(topic, schema_name, schema_encoding, encoding, TopicQos::Stream)
    }

    /// [`Ros2::add_channel`] with the topic's QoS.
    pub fn add_channel_qos(&mut self, topic: &str, schema_name: &str, schema_encoding: &str, encoding: &str, qos: TopicQos) -> Result<usize> {
        let writer = match (schema_encoding, encoding, dds_type_name(schema_name)) {
            ("ros2msg", "cdr", Some(type_name)) => {
                let policies = qos.policies();
                let t = self.participant.create_topic(dds_topic_name(topic), type_name, &policies, TopicKind::NoKey).map_err(|e| dds_error(topic, e))?;
                Some(self.publisher.create_datawriter_no_key::<RawCdr, RawAdapter>(&t, Some(policies)).map_err(|e| dds_error(topic, e))?)
            }
            _ => None,
        };
        self.writers.push(writer);
        Ok(self.writers.len() - 1)
    }

    /// Whether channel `channel` is published.
    pub fn carries(&self, channel: usize) -> bool {
        self.writers.get(channel).is_some_and(|w| w.is_some())
    }

    /// Publish one message (CDR with its header) on channel `channel`. A reader that does not
    /// keep up loses the oldest samples (keep last 10); nothing here waits for it beyond the
    /// reliable writer's 100 ms.
    pub fn log(&self, channel: usize, data: &[u8]) {
        if let Some(Some(w)) = self.writers.get(channel) {
            // A failed write (a reader gone mid-write) is not the run's failure.
            let _ = w.write(RawCdr(data.to_vec()), None);
        }
    }

    /// Subscribe to command topic `topic` of ROS type `ros_type`; its index for [`Ros2::take`].
    pub fn subscribe(&mut self, topic: &str, ros_type: &str) -> Result<usize> {
        let type_name = dds_type_name(ros_type).ok_or_else(|| dds_error(topic, format!("`{ros_type}` is not a ROS 2 message type")))?;
        let t = self.participant.create_topic(dds_topic_name(topic), type_name, &self.qos, TopicKind::NoKey).map_err(|e| dds_error(topic, e))?;
        let reader = self.subscriber.create_simple_datareader_no_key::<RawCdr, RawAdapter>(&t, None).map_err(|e| dds_error(topic, e))?;
        self.commands.push(Command { topic: topic.into(), reader });
        Ok(self.commands.len() - 1)
    }

    /// The topic of command subscription `command`.
    pub fn command_topic(&self, command: usize) -> &str {
        &self.commands[command].topic
    }

    /// The next message on command subscription `command` (CDR with its header), if one came;
    /// a message DDS could not hand over is an error naming the topic.
    pub fn take(&self, command: usize) -> Option<std::result::Result<Vec<u8>, String>> {
        let c = &self.commands[command];
        match c.reader.try_take_one() {
            Ok(Some(change)) => Some(Ok(change.into_value().0)),
            Ok(None) => None,
            Err(e) => Some(Err(format!("{}: {e}", c.topic))),
        }
    }

    /// A line on `/rosout`, stamped with the wall clock, at `level` (20 info, 30 warn, 40 error);
    /// whether it was taken. It never waits: when the reliable send window is full (a reader
    /// that does not acknowledge) the line is refused at once.
    pub fn log_line(&self, level: u8, text: &str) -> bool {
        let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64());
        self.rosout.write(RawCdr(ros_msgs::encode_log(t, level, &self.node, text)), None).is_ok()
    }
}
