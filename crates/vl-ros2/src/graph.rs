//! The ROS 2 graph as rmw_zenoh puts it on Zenoh: a node and its
//! publishers and subscriptions each announced by a liveliness token under
//! `@ros2_lv/`, topics at `<domain>/<topic>/<DDS type>/<RIHS01 hash>`,
//! each sample CDR with an attachment (sequence number, source time,
//! publisher GID), and a latched topic served to late subscribers by
//! rmw_zenoh's own caching publisher (zenoh-ext's `AdvancedPublisher`).

use std::marker::PhantomData;
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, AtomicU32, Ordering};

use sha2::{Digest, Sha256};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher as ZenohPublisher;
use zenoh::qos::CongestionControl;
use zenoh_ext::{AdvancedPublisher, AdvancedPublisherBuilderExt, CacheConfig, MissDetectionConfig};

use super::Ros2Error;
use super::messages::Message;
use super::msg::{MessageDefinitions, dds_name};
use vl_host::Hush;

/// The largest sample taken from a subscription (a camera's frame is far
/// smaller): a larger one is dropped before it is decoded.
const MAX_SAMPLE: usize = 16 << 20;

/// How a topic's samples are kept and delivered, as its token says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Qos {
    /// Every sample delivered (the sender waits), or the newest wins.
    pub(crate) reliable: bool,
    /// Latched: the newest `depth` samples wait for late subscribers.
    pub(crate) transient_local: bool,
    pub(crate) depth: u32,
}

impl Qos {
    /// What a stream of state takes: reliable, volatile, the newest 10.
    pub(crate) const STATE: Qos = Qos {
        reliable: true,
        transient_local: false,
        depth: 10,
    };
    /// What a camera takes (ROS's sensor-data profile): best effort, 5.
    pub(crate) const SENSOR: Qos = Qos {
        reliable: false,
        transient_local: false,
        depth: 5,
    };
    /// A map: reliable and latched, the newest one.
    pub(crate) const LATCHED: Qos = Qos {
        reliable: true,
        transient_local: true,
        depth: 1,
    };

    /// rmw_zenoh's QoS chunk: `reliability:durability:history,depth:
    /// deadline:lifespan:liveliness` with rmw's enum numbers. Every field
    /// the lab sets is written out, so no reader's defaults change it;
    /// empty durations are rmw's infinite ones.
    pub(crate) fn token_chunk(self) -> String {
        let reliability = if self.reliable { 1 } else { 2 };
        let durability = if self.transient_local { 1 } else { 2 };
        format!("{reliability}:{durability}:1,{}:,:,:,,", self.depth)
    }
}

/// `/` written as rmw_zenoh writes it inside one chunk of a token.
fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// A ROS 2 node on a Zenoh session.
pub(crate) struct Node {
    session: zenoh::Session,
    domain: u32,
    zid: String,
    /// `/` or `/NAME`.
    namespace: String,
    name: String,
    /// Node and entity ids, unique within the session.
    ids: Arc<AtomicU32>,
    nid: u32,
    catalogue: Arc<MessageDefinitions>,
    _token: LivelinessToken,
}

impl Node {
    /// Node `name` of `domain`, in the root namespace or `/NAME` (a
    /// cell's: its topics are then `/NAME/…`), announced at once.
    pub(crate) async fn new(
        session: zenoh::Session,
        domain: u32,
        namespace: Option<&str>,
        name: &str,
        catalogue: Arc<MessageDefinitions>,
    ) -> Result<Node, Ros2Error> {
        let namespace = match namespace {
            Some(inner) => format!("/{inner}"),
            None => "/".to_owned(),
        };
        let zid = session.zid().to_string();
        let ids = Arc::new(AtomicU32::new(0));
        let nid = ids.fetch_add(1, Ordering::Relaxed);
        let key = format!(
            "@ros2_lv/{domain}/{zid}/{nid}/{nid}/NN/%/{}/{}",
            mangle(&namespace),
            mangle(name)
        );
        let token = session.liveliness().declare_token(key).await?;
        Ok(Node {
            session,
            domain,
            zid,
            namespace,
            name: name.to_owned(),
            ids,
            nid,
            catalogue,
            _token: token,
        })
    }

    /// The data key of `topic` carrying `M`, and its endpoint token's key
    /// for an entity of `kind` (`MP` publisher, `MS` subscription).
    fn keys<M: Message>(&self, topic: &str, kind: &str, qos: Qos) -> Result<Keys, Ros2Error> {
        let hash = self.catalogue.type_hash(M::TYPE)?;
        let dds = dds_name(M::TYPE);
        let eid = self.ids.fetch_add(1, Ordering::Relaxed);
        // A relative name is within the node's namespace.
        let topic = format!("{}{topic}", self.namespace.trim_end_matches('/'));
        let data = format!(
            "{}/{}/{dds}/{hash}",
            self.domain,
            topic.trim_start_matches('/')
        );
        let token = format!(
            "@ros2_lv/{}/{}/{}/{eid}/{kind}/%/{}/{}/{}/{dds}/{hash}/{}",
            self.domain,
            self.zid,
            self.nid,
            mangle(&self.namespace),
            mangle(&self.name),
            mangle(&topic),
            qos.token_chunk()
        );
        Ok(Keys { data, token })
    }

    /// A publisher of `M` on `topic`.
    pub(crate) async fn publisher<M: Message>(
        &self,
        topic: &str,
        qos: Qos,
    ) -> Result<Publisher<M>, Ros2Error> {
        let keys = self.keys::<M>(topic, "MP", qos)?;
        let congestion = if qos.reliable {
            CongestionControl::Block
        } else {
            CongestionControl::Drop
        };
        let sender = if qos.transient_local {
            let cached = self
                .session
                .declare_publisher(keys.data.clone())
                .congestion_control(congestion)
                .cache(CacheConfig::default().max_samples(qos.depth as usize))
                .sample_miss_detection(MissDetectionConfig::default())
                .publisher_detection()
                .await?;
            Sender::Cached(cached)
        } else {
            let plain = self
                .session
                .declare_publisher(keys.data.clone())
                .congestion_control(congestion)
                .await?;
            Sender::Plain(plain)
        };
        let token = self
            .session
            .liveliness()
            .declare_token(keys.token.clone())
            .await?;
        Ok(Publisher {
            sender,
            gid: gid(&keys.token),
            sequence: AtomicI64::new(0),
            _token: token,
            _message: PhantomData,
        })
    }

    /// Every sample of `M` on `topic`, decoded, into `deliver` with who
    /// says it sent it (its attachment's); one that does not decode is
    /// dropped with a warning naming the topic (at most one a second: a
    /// publisher of garbage does not flood the log).
    pub(crate) async fn subscribe<M, F>(
        &self,
        topic: &str,
        qos: Qos,
        deliver: F,
    ) -> Result<TopicSubscription, Ros2Error>
    where
        M: Message + Send + 'static,
        F: Fn(M, Option<Origin>) + Send + Sync + 'static,
    {
        let keys = self.keys::<M>(topic, "MS", qos)?;
        let topic = topic.to_owned();
        let hush = Hush::default();
        let too_large = Hush::default();
        let subscriber = self
            .session
            .declare_subscriber(keys.data.clone())
            .callback(move |sample| {
                let payload = sample.payload();
                if payload.len() > MAX_SAMPLE {
                    if too_large.speak() {
                        tracing::warn!(
                            "ROS 2 {topic}: a sample of {} bytes, over the {MAX_SAMPLE} taken, dropped",
                            payload.len()
                        );
                    }
                    return;
                }
                match M::decode(&payload.to_bytes()) {
                    Ok(message) => {
                        let origin = sample.attachment().and_then(|a| Origin::of(&a.to_bytes()));
                        deliver(message, origin);
                    }
                    Err(e) if hush.speak() => {
                        tracing::warn!("ROS 2 {topic}: a {} that does not decode: {e}", M::TYPE)
                    }
                    Err(_) => {}
                }
            })
            .await?;
        let token = self.session.liveliness().declare_token(keys.token).await?;
        Ok(TopicSubscription {
            _subscriber: subscriber,
            _token: token,
        })
    }
}

struct Keys {
    data: String,
    token: String,
}

/// An entity's GID: rmw_zenoh derives it from its token; so does the lab
/// (its first 16 bytes of SHA-256).
fn gid(token: &str) -> [u8; 16] {
    let digest = Sha256::digest(token.as_bytes());
    let mut gid = [0; 16];
    gid.copy_from_slice(&digest[..16]);
    gid
}

/// rmw_zenoh's attachment: sequence number and source time (ns) as
/// little-endian i64, then the GID as a sequence (its length, 16, in one
/// byte, and its bytes).
pub(crate) fn attachment(sequence: i64, source_ns: i64, gid: &[u8; 16]) -> Vec<u8> {
    let mut out = Vec::with_capacity(33);
    out.extend(sequence.to_le_bytes());
    out.extend(source_ns.to_le_bytes());
    out.push(16);
    out.extend(gid);
    out
}

/// Who a sample says sent it, by its attachment: the publisher's GID
/// and the sample's number in its stream. Anyone may write any GID; a
/// publisher's numbers only ever grow, so a second source writing the
/// same GID shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Origin {
    pub(crate) gid: Vec<u8>,
    pub(crate) sequence: i64,
}

impl Origin {
    /// Reads an attachment as `attachment` writes it.
    pub(crate) fn of(attachment: &[u8]) -> Option<Origin> {
        let sequence = i64::from_le_bytes(attachment.get(..8)?.try_into().ok()?);
        let length = usize::from(*attachment.get(16)?);
        let gid = attachment.get(17..17 + length)?.to_vec();
        Some(Origin { gid, sequence })
    }
}

enum Sender {
    Plain(ZenohPublisher<'static>),
    Cached(AdvancedPublisher<'static>),
}

/// A typed publisher, announced while it lives.
pub(crate) struct Publisher<M> {
    sender: Sender,
    gid: [u8; 16],
    sequence: AtomicI64,
    _token: LivelinessToken,
    _message: PhantomData<fn(&M)>,
}

impl<M: Message> Publisher<M> {
    /// The payload and attachment of the next sample of `message`.
    fn sample(&self, message: &M) -> (Vec<u8>, Vec<u8>) {
        let sequence = self.sequence.fetch_add(1, Ordering::Relaxed);
        let source_ns = i64::try_from(vl_record::now_ns()).unwrap_or(i64::MAX);
        (message.encode(), attachment(sequence, source_ns, &self.gid))
    }

    pub(crate) async fn put(&self, message: &M) -> Result<(), Ros2Error> {
        let (payload, attachment) = self.sample(message);
        let encoding = zenoh::bytes::Encoding::APPLICATION_CDR;
        match &self.sender {
            Sender::Plain(p) => {
                p.put(payload)
                    .encoding(encoding)
                    .attachment(attachment)
                    .await?
            }
            Sender::Cached(p) => {
                p.put(payload)
                    .encoding(encoding)
                    .attachment(attachment)
                    .await?
            }
        }
        Ok(())
    }

    /// `put`, from a thread outside the async runtime (a robot driver's).
    pub(crate) fn put_wait(&self, message: &M) -> Result<(), Ros2Error> {
        use zenoh::Wait;
        let (payload, attachment) = self.sample(message);
        let encoding = zenoh::bytes::Encoding::APPLICATION_CDR;
        match &self.sender {
            Sender::Plain(p) => p
                .put(payload)
                .encoding(encoding)
                .attachment(attachment)
                .wait()?,
            Sender::Cached(p) => p
                .put(payload)
                .encoding(encoding)
                .attachment(attachment)
                .wait()?,
        }
        Ok(())
    }

    /// Whether some subscriber takes this topic now.
    pub(crate) async fn matched(&self) -> bool {
        let status = match &self.sender {
            Sender::Plain(p) => p.matching_status().await,
            Sender::Cached(p) => p.matching_status().await,
        };
        status.is_ok_and(|s| s.matching())
    }
}

/// A subscription, announced while it lives.
pub(crate) struct TopicSubscription {
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _token: LivelinessToken,
}
