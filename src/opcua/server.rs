//! The OPC UA server: async-opcua on a thread and a runtime of its own, serving one
//! machine tool object per machine. Runs reach it only through [`Feed::apply`], which hands
//! the tracker's message over a bounded channel without waiting (a full channel counts the
//! message as lost), so no client, however slow or many, reaches a run.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{simple_node_manager, SimpleNodeManager};
use opcua::server::{ServerBuilder, ServerHandle, SubscriptionCache};
use opcua::types::{DataValue, DateTime};
use tokio::sync::mpsc;

use crate::config::opcua::{OpcUaSettings, Security};
use crate::config::telemetry::topic_name;
use crate::opcua::alert::AlertEvent;
use crate::opcua::machine_tool::MachineTool;
use crate::opcua::nodes::{self, Identity, MachineNodes, Namespaces};
use crate::opcua::security;
use crate::telemetry::tracker::Out;

/// The messages the runs may hand over before the server's thread takes them.
const INPUTS: usize = 4096;

/// Why the server cannot serve.
#[derive(Debug, thiserror::Error)]
pub enum OpcUaError {
    /// A setting cannot be used: the key (or flag) and what is wrong.
    #[error("{key}: {problem}")]
    Settings {
        /// The key or flag.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// The address cannot be listened on.
    #[error("{key}: cannot listen on {address}: {source}")]
    Listen {
        /// The key or flag that named the address.
        key: String,
        /// The address.
        address: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// async-opcua refused its configuration.
    #[error("the OPC UA server cannot start: {0}")]
    Server(String),
    /// No thread for the server.
    #[error("no thread for the OPC UA server: {0}")]
    Thread(std::io::Error),
}

/// What the runs hand the server's thread: one machine's tracker message.
struct Input {
    machine: usize,
    out: Out,
}

/// A serving OPC UA server, until [`OpcUa::close`].
pub struct OpcUa {
    inputs: mpsc::Sender<Input>,
    lost: Arc<AtomicU64>,
    handle: ServerHandle,
    thread: std::thread::JoinHandle<()>,
    address: SocketAddr,
    names: Vec<String>,
}

/// What one machine's telemetry hands its messages through: clonable, never waiting.
#[derive(Clone)]
pub struct Feed {
    inputs: mpsc::Sender<Input>,
    lost: Arc<AtomicU64>,
    machine: usize,
}

impl OpcUa {
    /// Serves `machines` with `settings` (checked: [`OpcUaSettings::new`]); `key` names
    /// the address's source in a refusal (`opcua`, `--opcua`). It listens before it
    /// returns: an address in use is refused here.
    pub fn start(
        settings: &OpcUaSettings,
        key: &str,
        machines: &[Identity],
    ) -> Result<OpcUa, OpcUaError> {
        let pki = match (&settings.pki, settings.security) {
            (Some(pki), _) => pki.clone(),
            // An unsecured server keeps no certificate: no folder is used.
            (None, Security::None) => std::path::PathBuf::new(),
            (None, _) => security::default_pki(
                std::env::var_os("XDG_DATA_HOME").as_deref(),
                std::env::var_os("HOME").as_deref(),
            )
            .ok_or_else(|| OpcUaError::Settings {
                key: "opcua_pki".into(),
                problem: "no home folder (HOME) to keep the server's certificate in: name a \
                          folder"
                    .into(),
            })?,
        };
        let (listener, address) =
            listen(settings.address).map_err(|source| OpcUaError::Listen {
                key: key.into(),
                address: settings.address,
                source,
            })?;
        let host = crate::records::Process::current().host;
        let mut builder = ServerBuilder::new()
            .application_name("whirl")
            .application_uri(format!("urn:{host}:whirl"))
            .product_uri("urn:whirl")
            .host(address.ip().to_string())
            .port(address.port())
            .discovery_urls(vec!["/".to_owned()]);
        for (uri, name) in [
            (nodes::MACHINE_TOOL, "machine-tool"),
            (nodes::DI, "di"),
            (nodes::MACHINERY, "machinery"),
            (nodes::IA, "ia"),
            (nodes::WHIRL, "whirl"),
        ] {
            builder = builder.with_node_manager(simple_node_manager(
                NamespaceMetadata {
                    namespace_uri: uri.to_owned(),
                    ..Default::default()
                },
                name,
            ));
        }
        let builder = security::secure(builder, settings, pki);
        // The server's runtime, made here: building the server spawns its samplers on it.
        // Its tasks run once the thread drives it.
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(OpcUaError::Thread)?;
        let entered = runtime.enter();
        let (server, handle) = builder.build().map_err(OpcUaError::Server)?;
        let index = |uri: &str| {
            handle
                .get_namespace_index(uri)
                .expect("each namespace has its node manager")
        };
        let ns = Namespaces {
            machine_tool: index(nodes::MACHINE_TOOL),
            di: index(nodes::DI),
            machinery: index(nodes::MACHINERY),
            ia: index(nodes::IA),
            whirl: index(nodes::WHIRL),
        };
        let manager = |name: &str| {
            handle
                .node_managers()
                .get_by_name::<SimpleNodeManager>(name)
                .expect("each namespace has its node manager")
        };
        let (types, machinery, whirl) = (
            manager("machine-tool"),
            manager("machinery"),
            manager("whirl"),
        );
        nodes::add_types(
            &mut types.address_space().write(),
            &mut machinery.address_space().write(),
            &ns,
        );
        let mut served = Vec::new();
        let mut keys: Vec<String> = Vec::new();
        for identity in machines {
            let mut key = topic_name(&identity.name);
            if key.is_empty() || keys.contains(&key) {
                key = format!("machine-{}", keys.len() + 1);
            }
            keys.push(key.clone());
            let nodes = MachineNodes::new(ns, &key);
            let tool = MachineTool::new();
            nodes.insert(&mut whirl.address_space().write(), identity, tool.values());
            served.push(Served {
                name: identity.name.clone(),
                nodes,
                tool,
            });
        }
        let listener =
            tokio::net::TcpListener::from_std(listener).map_err(|source| OpcUaError::Listen {
                key: key.into(),
                address,
                source,
            })?;
        drop(entered);
        let (inputs, receiver) = mpsc::channel(INPUTS);
        let serving = Serving {
            machines: served,
            manager: whirl,
            subscriptions: handle.subscriptions().clone(),
            machine_tool: ns.machine_tool,
            stop: handle.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("whirl-opcua".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let server = tokio::spawn(server.run_with(listener));
                    serving.follow(receiver).await;
                    if let Ok(Err(e)) = server.await {
                        tracing::error!("opcua: the server ended: {e}");
                    }
                });
            })
            .map_err(OpcUaError::Thread)?;
        Ok(OpcUa {
            inputs,
            lost: Arc::new(AtomicU64::new(0)),
            handle,
            thread,
            address,
            names: machines.iter().map(|m| m.name.clone()).collect(),
        })
    }

    /// Where it listens (the port the system gave, for port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The feed of the machine named `name` (as its [`Identity`] names it), if served.
    pub fn feed(&self, name: &str) -> Option<Feed> {
        let machine = self.names.iter().position(|n| n == name)?;
        Some(Feed {
            inputs: self.inputs.clone(),
            lost: self.lost.clone(),
            machine,
        })
    }

    /// Stops serving: the sessions are ended and the thread joined. It blocks: from async
    /// code, call it on a blocking thread. Returns the messages lost to a full channel.
    pub fn close(self) -> u64 {
        self.handle.cancel();
        drop(self.inputs);
        let _ = self.thread.join();
        self.lost.load(Ordering::Relaxed)
    }
}

/// A non-blocking listener on `address`, and the address it got (its port, for port 0).
fn listen(address: SocketAddr) -> std::io::Result<(std::net::TcpListener, SocketAddr)> {
    let listener = std::net::TcpListener::bind(address)?;
    listener.set_nonblocking(true)?;
    let address = listener.local_addr()?;
    Ok((listener, address))
}

impl Feed {
    /// One of the machine's tracker messages, handed over without waiting (counted as lost
    /// if the channel is full).
    pub fn apply(&self, out: &Out) {
        let input = Input {
            machine: self.machine,
            out: out.clone(),
        };
        if self.inputs.try_send(input).is_err() {
            self.lost.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// One machine as served: its name, its nodes and its values.
struct Served {
    name: String,
    nodes: MachineNodes,
    tool: MachineTool,
}

/// The server's side of the channel: the machines' values into their nodes.
struct Serving {
    machines: Vec<Served>,
    manager: Arc<SimpleNodeManager>,
    subscriptions: Arc<SubscriptionCache>,
    machine_tool: u16,
    /// The server, whose token is cancelled when it closes (the feeds may outlive it).
    stop: ServerHandle,
}

impl Serving {
    /// Takes the runs' messages until the server closes.
    async fn follow(mut self, mut inputs: mpsc::Receiver<Input>) {
        loop {
            let input = tokio::select! {
                input = inputs.recv() => input,
                () = self.stop.token().cancelled() => None,
            };
            let Some(Input { machine, out }) = input else {
                return;
            };
            let Some(served) = self.machines.get_mut(machine) else {
                continue;
            };
            let alerts = served.tool.apply(&out);
            let writes = served.nodes.writes(served.tool.values());
            let now = DateTime::now();
            let values = writes.iter().map(|(id, value)| {
                let value = DataValue::new_at(value.clone(), now);
                (id, None, value)
            });
            if let Err(status) = self.manager.set_values(&self.subscriptions, values) {
                tracing::warn!("opcua: {}: a value was not written ({status})", served.name);
            }
            // From Messages; async-opcua hands it to the Server object's subscribers too.
            let messages = served.nodes.messages();
            for alert in alerts {
                let event =
                    AlertEvent::new(&alert, &served.name, &messages, self.machine_tool, now);
                let event: &dyn opcua::nodes::Event = &event;
                self.subscriptions
                    .notify_events(std::iter::once((event, &messages)));
            }
        }
    }
}
