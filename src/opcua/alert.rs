//! An alarm as OPC 40501-1's `AlertType` event (9.1): an `AlarmConditionType` whose
//! `ErrorCode` is the controller's code and whose `Message` is what it means, raised
//! (`ActiveState` true, `Retain` true) when the controller alarms and cleared when the next
//! run starts. It comes from the machine's `Notification/Messages` and from the `Server`
//! object, so that a client subscribed to either sees it.
//!
//! The event is all there is of the condition: no condition instance is kept in the address
//! space, so it cannot be acknowledged, and ConditionRefresh replays nothing.

use opcua::core_namespace::events::AlarmConditionType;
use opcua::types::{ByteString, DateTime, LocalizedText, NamespaceMap, NodeId, UAString};

use crate::opcua::machine_tool::Alert;
use crate::opcua::nodes::ALERT_TYPE;

/// OPC 40501-1's `AlertType`, with the one property it adds. Crate-wide only: the derive
/// makes constructors of its own, which the server does not use.
#[derive(Debug, opcua::Event)]
#[opcua(
    identifier = "i=39",
    namespace = "http://opcfoundation.org/UA/MachineTool/"
)]
pub(crate) struct AlertEvent {
    base: AlarmConditionType,
    own_namespace_index: u16,
    /// The controller's code.
    error_code: UAString,
}

impl AlertEvent {
    /// `alert` of the machine named `machine`, from its `messages` node; `machine_tool`
    /// is the MachineTool namespace's index, `time` when it happened.
    pub(crate) fn new(
        alert: &Alert,
        machine: &str,
        messages: &NodeId,
        machine_tool: u16,
        time: DateTime,
    ) -> AlertEvent {
        let type_id = NodeId::new(machine_tool, ALERT_TYPE);
        let mut base = AlarmConditionType::new_event(
            type_id,
            event_id(),
            LocalizedText::from(alert.message.as_str()),
            &NamespaceMap::new(),
            time,
        );
        let event = &mut base.base.base.base;
        event.source_node = messages.clone();
        event.source_name = UAString::from(machine);
        event.severity = Alert::SEVERITY;
        let condition = &mut base.base.base;
        condition.condition_name = UAString::from(format!("Alarm {}", alert.error_code));
        condition.retain = alert.active;
        condition.enabled_state.id = true;
        // `ActiveState/Id` is what a client reads: async-opcua 0.19 answers a two-state
        // variable's own value (its text) empty.
        base.active_state.id = alert.active;
        AlertEvent {
            base,
            own_namespace_index: machine_tool,
            error_code: UAString::from(alert.error_code.as_str()),
        }
    }
}

/// A fresh EventId: sixteen random bytes (or the clock's nanoseconds, without randomness
/// from the OS).
fn event_id() -> ByteString {
    let mut bytes = [0u8; 16];
    if getrandom::fill(&mut bytes).is_err() {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        bytes = now.as_nanos().to_le_bytes();
    }
    ByteString::from(bytes.to_vec())
}
