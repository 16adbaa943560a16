//! The machines' nodes in the server's address space, as OPC 40501-1 names them: each
//! machine an object under `Objects/Machines` (OPC 40001-1's entry point, found by its
//! standard NodeId too) with its `Identification`, `Monitoring`, `Production`,
//! `Notification` and `Equipment`.
//!
//! The companion specifications' NodeSets are not loaded (async-opcua would need its XML
//! reader and the NodeSet files): the objects carry the specifications' BrowseNames in
//! their namespaces (`http://opcfoundation.org/UA/MachineTool/`, `…/DI/`, `…/Machinery/`,
//! `…/IA/`), and their type definitions are the MachineTool types' standard NodeIds. Those
//! types are present as nodes with their BrowseNames and supertypes but without their
//! instance declarations, so a client that checks an instance against its type finds the
//! type, not its members (`docs/opcua.md` says what is and is not typed). The instances'
//! own NodeIds are whirl's (`urn:whirl:machines`): `MACHINE/Monitoring/Channel_1/ChannelState`.

use opcua::server::address_space::{
    AddressSpace, DataTypeBuilder, EventNotifier, ObjectBuilder, ObjectTypeBuilder,
    ReferenceDirection, VariableBuilder,
};
use opcua::types::{
    DataTypeId, EUInformation, EnumValueType, ExtensionObject, LocalizedText, NodeId, ObjectId,
    ObjectTypeId, QualifiedName, Range, ReferenceTypeId, VariableTypeId, Variant,
};

use crate::config::opcua::Nameplate;
use crate::config::telemetry::topic_name;
use crate::opcua::machine_tool::{ProductionState, Values, LAMPS};

/// OPC 40501-1's namespace.
pub const MACHINE_TOOL: &str = "http://opcfoundation.org/UA/MachineTool/";
/// OPC 10000-100's (Devices): the nameplate's properties.
pub const DI: &str = "http://opcfoundation.org/UA/DI/";
/// OPC 40001-1's (Machinery): the `Machines` folder.
pub const MACHINERY: &str = "http://opcfoundation.org/UA/Machinery/";
/// OPC 10000-200's (Industrial Automation): the stacklight's members.
pub const IA: &str = "http://opcfoundation.org/UA/IA/";
/// whirl's own: the instances' NodeIds, the names 40501-1 leaves to the server (a
/// machine, its channel, its lamps, its job) and whirl's additions (`Line`, `Percent`).
pub const WHIRL: &str = "urn:whirl:machines";

/// `Machines`' NodeId in the Machinery namespace (OPC 40001-1, 9.2).
const MACHINES: u32 = 1001;
/// `AlertType`'s NodeId in the MachineTool namespace, and its `ErrorCode`'s.
pub const ALERT_TYPE: u32 = 39;
const ALERT_TYPE_ERROR_CODE: u32 = 231;
/// `AnalogUnitRangeType` (OPC 10000-8), the type of a `FeedOverride`.
const ANALOG_UNIT_RANGE_TYPE: u32 = 17570;
/// UNECE's code for percent (`P1`), as OPC UA's EUInformation numbers it.
const PERCENT_UNIT_ID: i32 = 20529;
/// The widest feed override whirl's controllers take (grbl's 10 to 200 %).
const FEED_OVERRIDE_RANGE: (f64, f64) = (0.0, 200.0);

/// The namespace index the server gave each URI.
#[derive(Debug, Clone, Copy)]
pub struct Namespaces {
    /// [`MACHINE_TOOL`].
    pub machine_tool: u16,
    /// [`DI`].
    pub di: u16,
    /// [`MACHINERY`].
    pub machinery: u16,
    /// [`IA`].
    pub ia: u16,
    /// [`WHIRL`].
    pub whirl: u16,
}

impl Namespaces {
    /// The `Machines` folder's NodeId.
    pub fn machines(&self) -> NodeId {
        NodeId::new(self.machinery, MACHINES)
    }

    /// A MachineTool type's NodeId.
    pub fn machine_tool_type(&self, id: u32) -> NodeId {
        NodeId::new(self.machine_tool, id)
    }
}

/// A 40501-1 ObjectType this server names: its NodeId in the MachineTool namespace, its
/// BrowseName and its supertype (in namespace 0, or another of these).
struct TypeNode {
    id: u32,
    name: &'static str,
    supertype: Super,
}

enum Super {
    Base(ObjectTypeId),
    MachineTool(u32),
}

/// The MachineTool types the machines' objects are instances of (ids from the
/// specification's NodeIds.csv). A supertype in another companion namespace (the
/// identification's `3:MachineIdentificationType`) is BaseObjectType here.
const TYPES: [TypeNode; 19] = [
    type_node(
        7,
        "NotificationType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        11,
        "MachineToolIdentificationType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        12,
        "EquipmentType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        13,
        "MachineToolType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        14,
        "MonitoringType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        23,
        "ElementMonitoringType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(16, "ChannelMonitoringType", Super::MachineTool(23)),
    type_node(
        26,
        "MachineOperationMonitoringType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        21,
        "ProductionType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        59,
        "ProductionProgramType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(32, "ProductionActiveProgramType", Super::MachineTool(59)),
    type_node(
        30,
        "ProductionJobListType",
        Super::Base(ObjectTypeId::OrderedListType),
    ),
    type_node(
        29,
        "ProductionJobType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        24,
        "ProductionStateMachineType",
        Super::Base(ObjectTypeId::FiniteStateMachineType),
    ),
    type_node(
        15,
        "ProductionProgramStateMachineType",
        Super::MachineTool(24),
    ),
    type_node(28, "ProductionJobStateMachineType", Super::MachineTool(24)),
    type_node(
        38,
        "MessagesType",
        Super::Base(ObjectTypeId::BaseObjectType),
    ),
    type_node(
        ALERT_TYPE,
        "AlertType",
        Super::Base(ObjectTypeId::AlarmConditionType),
    ),
    type_node(
        35,
        "NotificationEventType",
        Super::Base(ObjectTypeId::BaseEventType),
    ),
];

const fn type_node(id: u32, name: &'static str, supertype: Super) -> TypeNode {
    TypeNode {
        id,
        name,
        supertype,
    }
}

/// The 40501-1 enumerations whirl's values are of: NodeId, BrowseName, and the names of
/// values 0, 1, ….
const ENUMERATIONS: [(u32, &str, &[&str]); 3] = [
    (64, "ChannelState", &["Active", "Interrupted", "Reset"]),
    (
        65,
        "MachineOperationMode",
        &[
            "Manual",
            "Automatic",
            "Setup",
            "AutoWithManualIntervention",
            "Service",
            "Other",
        ],
    ),
    (
        67,
        "ChannelMode",
        &[
            "Automatic",
            "MdaMdi",
            "JogManual",
            "JogIncrement",
            "TeachingHandle",
            "Remote",
            "Reference",
            "Other",
        ],
    ),
];
const CHANNEL_STATE: u32 = 64;
const MACHINE_OPERATION_MODE: u32 = 65;
const CHANNEL_MODE: u32 = 67;
/// `ChannelMode`'s `Automatic`: whirl executes part programs.
const CHANNEL_MODE_AUTOMATIC: i32 = 0;
/// `StacklightOperationMode`'s `Segmented` (OPC 10000-200), which 40501-1 requires.
const STACKLIGHT_SEGMENTED: i32 = 0;
/// `SignalModeLight`'s `Continuous` (OPC 10000-200): whirl's lamps do not blink.
const SIGNAL_CONTINUOUS: i32 = 0;

/// The MachineTool types and enumerations, into the MachineTool namespace's address space
/// (`space` owns `ns.machine_tool`), and the `Machines` folder into the Machinery one's.
pub fn add_types(types: &mut AddressSpace, machinery: &mut AddressSpace, ns: &Namespaces) {
    for t in &TYPES {
        let supertype = match t.supertype {
            Super::Base(id) => NodeId::from(id),
            Super::MachineTool(id) => ns.machine_tool_type(id),
        };
        ObjectTypeBuilder::new(
            &ns.machine_tool_type(t.id),
            QualifiedName::new(ns.machine_tool, t.name),
            t.name,
        )
        .is_abstract(false)
        .subtype_of(supertype)
        .insert(types);
    }
    VariableBuilder::new(
        &ns.machine_tool_type(ALERT_TYPE_ERROR_CODE),
        QualifiedName::new(ns.machine_tool, "ErrorCode"),
        "ErrorCode",
    )
    .data_type(DataTypeId::String)
    .property_of(ns.machine_tool_type(ALERT_TYPE))
    .has_type_definition(VariableTypeId::PropertyType)
    .has_modelling_rule(ObjectId::ModellingRule_Mandatory)
    .insert(types);
    for (id, name, values) in ENUMERATIONS {
        let data_type = ns.machine_tool_type(id);
        DataTypeBuilder::new(&data_type, QualifiedName::new(ns.machine_tool, name), name)
            .subtype_of(DataTypeId::Enumeration)
            .insert(types);
        let enum_values: Vec<ExtensionObject> = values
            .iter()
            .zip(0..)
            .map(|(name, value)| {
                ExtensionObject::from_message(EnumValueType {
                    value,
                    display_name: LocalizedText::from(*name),
                    description: LocalizedText::null(),
                })
            })
            .collect();
        VariableBuilder::new(
            &NodeId::new(ns.machine_tool, format!("{name}_EnumValues")),
            "EnumValues",
            "EnumValues",
        )
        .data_type(DataTypeId::EnumValueType)
        .value_rank(1)
        .value(Variant::from(enum_values))
        .property_of(data_type)
        .has_type_definition(VariableTypeId::PropertyType)
        .insert(types);
    }
    ObjectBuilder::new(
        &ns.machines(),
        QualifiedName::new(ns.machinery, "Machines"),
        "Machines",
    )
    .description("The entry point to the machines this server serves (OPC 40001-1)")
    .organized_by(ObjectId::ObjectsFolder)
    .has_type_definition(ObjectTypeId::FolderType)
    .insert(machinery);
}

/// What a machine's `Identification` says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// The machine's name: its object's BrowseName.
    pub name: String,
    /// `Manufacturer`.
    pub manufacturer: String,
    /// `Model`.
    pub model: String,
    /// `ProductInstanceUri`.
    pub product_instance_uri: String,
    /// `SerialNumber`, if the shop gives one.
    pub serial_number: Option<String>,
    /// `SoftwareRevision`: whirl's version.
    pub software_revision: String,
}

impl Identity {
    /// The identification of the machine named `name` (its profile's name), from what its
    /// profile's `[telemetry]` says (`nameplate`) and the defaults: "whirl" makes it, its
    /// model is its name, and its URI names this host and it.
    pub fn new(name: &str, nameplate: &Nameplate) -> Identity {
        let host = crate::records::Process::current().host;
        Identity {
            name: name.to_owned(),
            manufacturer: nameplate
                .manufacturer
                .clone()
                .unwrap_or_else(|| "whirl".to_owned()),
            model: nameplate.model.clone().unwrap_or_else(|| name.to_owned()),
            product_instance_uri: nameplate
                .product_instance_uri
                .clone()
                .unwrap_or_else(|| format!("urn:{}:whirl:{}", topic_name(&host), topic_name(name))),
            serial_number: nameplate.serial_number.clone(),
            software_revision: env!("CARGO_PKG_VERSION").to_owned(),
        }
    }
}

/// One machine's nodes: where each value goes.
#[derive(Debug, Clone)]
pub struct MachineNodes {
    ns: Namespaces,
    /// The prefix of its NodeIds.
    key: String,
}

/// A variable of a machine and the value it now has.
pub type Write = (NodeId, Variant);

impl MachineNodes {
    /// The nodes of the machine whose NodeIds start with `key` (unique in the server).
    pub fn new(ns: Namespaces, key: &str) -> MachineNodes {
        MachineNodes {
            ns,
            key: key.to_owned(),
        }
    }

    /// The NodeId of the node at `path` under the machine (`""` for the machine itself).
    pub fn id(&self, path: &str) -> NodeId {
        if path.is_empty() {
            NodeId::new(self.ns.whirl, self.key.clone())
        } else {
            NodeId::new(self.ns.whirl, format!("{}/{path}", self.key))
        }
    }

    /// The `Notification/Messages` object, which alerts come from.
    pub fn messages(&self) -> NodeId {
        self.id("Notification/Messages")
    }

    /// Inserts the machine's objects and variables (into the whirl namespace's space),
    /// with `values` as their first values.
    pub fn insert(&self, space: &mut AddressSpace, identity: &Identity, values: &Values) {
        let ns = self.ns;
        let mt = |name: &str| QualifiedName::new(ns.machine_tool, name);
        let machine = self.id("");
        let object = |space: &mut AddressSpace, path: &str, name: QualifiedName, of: &str| {
            let parent = self.id(of);
            let id = self.id(path);
            ObjectBuilder::new(&id, name.clone(), name.name.as_ref())
                .component_of(parent)
                .insert(space);
            id
        };
        let typed = |space: &mut AddressSpace, id: &NodeId, type_id: NodeId| {
            space.insert_reference(id, &type_id, ReferenceTypeId::HasTypeDefinition);
        };
        ObjectBuilder::new(
            &machine,
            QualifiedName::new(ns.whirl, identity.name.as_str()),
            identity.name.as_str(),
        )
        .organized_by(ns.machines())
        .has_type_definition(ns.machine_tool_type(13))
        .insert(space);

        // Identification: an AddIn, its properties DI's.
        let identification = self.id("Identification");
        ObjectBuilder::new(
            &identification,
            QualifiedName::new(ns.di, "Identification"),
            "Identification",
        )
        .reference(
            machine.clone(),
            ReferenceTypeId::HasAddIn,
            ReferenceDirection::Inverse,
        )
        .has_type_definition(ns.machine_tool_type(11))
        .insert(space);
        let mut nameplate: Vec<(&str, Variant)> = vec![
            (
                "Manufacturer",
                LocalizedText::from(identity.manufacturer.as_str()).into(),
            ),
            ("Model", LocalizedText::from(identity.model.as_str()).into()),
            (
                "ProductInstanceUri",
                identity.product_instance_uri.as_str().into(),
            ),
            (
                "SoftwareRevision",
                identity.software_revision.as_str().into(),
            ),
        ];
        if let Some(serial) = &identity.serial_number {
            nameplate.push(("SerialNumber", serial.as_str().into()));
        }
        for (name, value) in nameplate {
            let data_type = match value {
                Variant::LocalizedText(_) => DataTypeId::LocalizedText,
                _ => DataTypeId::String,
            };
            property(
                space,
                self.id(&format!("Identification/{name}")),
                QualifiedName::new(ns.di, name),
                data_type,
                value,
                &identification,
            );
        }

        // Monitoring: the machine, its stacklight and its one channel.
        let monitoring = object(space, "Monitoring", mt("Monitoring"), "");
        typed(space, &monitoring, ns.machine_tool_type(14));
        let operation = object(
            space,
            "Monitoring/MachineTool",
            mt("MachineTool"),
            "Monitoring",
        );
        typed(space, &operation, ns.machine_tool_type(26));
        variable(
            space,
            self.id("Monitoring/MachineTool/OperationMode"),
            mt("OperationMode"),
            ns.machine_tool_type(MACHINE_OPERATION_MODE),
            Variant::Int32(values.operation_mode as i32),
            &operation,
        );
        let stacklight = object(
            space,
            "Monitoring/Stacklight",
            mt("Stacklight"),
            "Monitoring",
        );
        typed(space, &stacklight, ObjectTypeId::BaseObjectType.into());
        property(
            space,
            self.id("Monitoring/Stacklight/StacklightMode"),
            QualifiedName::new(ns.ia, "StacklightMode"),
            DataTypeId::Enumeration,
            Variant::Int32(STACKLIGHT_SEGMENTED),
            &stacklight,
        );
        for (number, (lamp, on)) in LAMPS.iter().zip(values.lamps).enumerate() {
            let name = format!("Lamp_{lamp:?}");
            let path = format!("Monitoring/Stacklight/{name}");
            let id = self.id(&path);
            ObjectBuilder::new(
                &id,
                QualifiedName::new(ns.whirl, name.as_str()),
                name.as_str(),
            )
            .reference(
                stacklight.clone(),
                ReferenceTypeId::HasOrderedComponent,
                ReferenceDirection::Inverse,
            )
            .has_type_definition(ObjectTypeId::BaseObjectType)
            .insert(space);
            property(
                space,
                self.id(&format!("{path}/NumberInList")),
                QualifiedName::new(0, "NumberInList"),
                DataTypeId::UInt16,
                Variant::UInt16(number as u16),
                &id,
            );
            property(
                space,
                self.id(&format!("{path}/SignalColor")),
                QualifiedName::new(ns.ia, "SignalColor"),
                DataTypeId::Enumeration,
                Variant::Int32(*lamp as i32),
                &id,
            );
            property(
                space,
                self.id(&format!("{path}/SignalMode")),
                QualifiedName::new(ns.ia, "SignalMode"),
                DataTypeId::Enumeration,
                Variant::Int32(SIGNAL_CONTINUOUS),
                &id,
            );
            variable(
                space,
                self.id(&format!("{path}/SignalOn")),
                QualifiedName::new(ns.ia, "SignalOn"),
                DataTypeId::Boolean.into(),
                Variant::Boolean(on),
                &id,
            );
        }
        let channel = self.id("Monitoring/Channel_1");
        ObjectBuilder::new(
            &channel,
            QualifiedName::new(ns.whirl, "Channel_1"),
            "Channel_1",
        )
        .component_of(monitoring.clone())
        .has_type_definition(ns.machine_tool_type(16))
        .insert(space);
        property(
            space,
            self.id("Monitoring/Channel_1/Name"),
            mt("Name"),
            DataTypeId::String,
            "Channel 1".into(),
            &channel,
        );
        variable(
            space,
            self.id("Monitoring/Channel_1/ChannelState"),
            mt("ChannelState"),
            ns.machine_tool_type(CHANNEL_STATE),
            Variant::Int32(values.channel_state as i32),
            &channel,
        );
        variable(
            space,
            self.id("Monitoring/Channel_1/ChannelMode"),
            mt("ChannelMode"),
            ns.machine_tool_type(CHANNEL_MODE),
            Variant::Int32(CHANNEL_MODE_AUTOMATIC),
            &channel,
        );
        let feed = self.id("Monitoring/Channel_1/FeedOverride");
        VariableBuilder::new(&feed, mt("FeedOverride"), "FeedOverride")
            .data_type(DataTypeId::Double)
            .value(values.feed_override)
            .component_of(channel.clone())
            .has_type_definition(NodeId::new(0, ANALOG_UNIT_RANGE_TYPE))
            .insert(space);
        property(
            space,
            self.id("Monitoring/Channel_1/FeedOverride/EngineeringUnits"),
            QualifiedName::new(0, "EngineeringUnits"),
            DataTypeId::EUInformation,
            ExtensionObject::from_message(EUInformation {
                namespace_uri: "http://www.opcfoundation.org/UA/units/un/cefact".into(),
                unit_id: PERCENT_UNIT_ID,
                display_name: LocalizedText::from("%"),
                description: LocalizedText::from("percent"),
            })
            .into(),
            &feed,
        );
        property(
            space,
            self.id("Monitoring/Channel_1/FeedOverride/EURange"),
            QualifiedName::new(0, "EURange"),
            DataTypeId::Range,
            ExtensionObject::from_message(Range {
                low: FEED_OVERRIDE_RANGE.0,
                high: FEED_OVERRIDE_RANGE.1,
            })
            .into(),
            &feed,
        );

        // Production: the active program and the job it belongs to.
        let production = object(space, "Production", mt("Production"), "");
        typed(space, &production, ns.machine_tool_type(21));
        let program = object(
            space,
            "Production/ActiveProgram",
            mt("ActiveProgram"),
            "Production",
        );
        typed(space, &program, ns.machine_tool_type(32));
        property(
            space,
            self.id("Production/ActiveProgram/Name"),
            mt("Name"),
            DataTypeId::String,
            values.program.as_str().into(),
            &program,
        );
        property(
            space,
            self.id("Production/ActiveProgram/NumberInList"),
            QualifiedName::new(0, "NumberInList"),
            DataTypeId::UInt16,
            Variant::UInt16(0),
            &program,
        );
        variable(
            space,
            self.id("Production/ActiveProgram/JobIdentifier"),
            mt("JobIdentifier"),
            DataTypeId::String.into(),
            values.job.as_str().into(),
            &program,
        );
        self.state_machine(space, "Production/ActiveProgram", 15, values.program_state);
        for (name, value) in [
            ("Line", Variant::UInt32(values.line.unwrap_or(0))),
            ("Percent", Variant::Double(values.percent)),
        ] {
            let data_type = match value {
                Variant::UInt32(_) => DataTypeId::UInt32,
                _ => DataTypeId::Double,
            };
            variable(
                space,
                self.id(&format!("Production/ActiveProgram/{name}")),
                QualifiedName::new(ns.whirl, name),
                data_type.into(),
                value,
                &program,
            );
        }
        let plan = object(
            space,
            "Production/ProductionPlan",
            mt("ProductionPlan"),
            "Production",
        );
        typed(space, &plan, ns.machine_tool_type(30));
        let job = self.id("Production/ProductionPlan/Job");
        ObjectBuilder::new(&job, QualifiedName::new(ns.whirl, "Job"), "Job")
            .reference(
                plan.clone(),
                ReferenceTypeId::HasOrderedComponent,
                ReferenceDirection::Inverse,
            )
            .has_type_definition(ns.machine_tool_type(29))
            .insert(space);
        property(
            space,
            self.id("Production/ProductionPlan/Job/Identifier"),
            mt("Identifier"),
            DataTypeId::String,
            values.job.as_str().into(),
            &job,
        );
        property(
            space,
            self.id("Production/ProductionPlan/Job/NumberInList"),
            QualifiedName::new(0, "NumberInList"),
            DataTypeId::UInt16,
            Variant::UInt16(0),
            &job,
        );
        variable(
            space,
            self.id("Production/ProductionPlan/Job/RunsCompleted"),
            mt("RunsCompleted"),
            DataTypeId::UInt32.into(),
            Variant::UInt32(values.runs_completed),
            &job,
        );
        // whirl is not told how many runs a job plans: RunsPlanned says it is not valid.
        let planned = self.id("Production/ProductionPlan/Job/RunsPlanned");
        variable(
            space,
            planned.clone(),
            mt("RunsPlanned"),
            DataTypeId::UInt32.into(),
            Variant::UInt32(0),
            &job,
        );
        property(
            space,
            self.id("Production/ProductionPlan/Job/RunsPlanned/IsValid"),
            mt("IsValid"),
            DataTypeId::Boolean,
            Variant::Boolean(false),
            &planned,
        );
        self.state_machine(space, "Production/ProductionPlan/Job", 28, values.job_state);

        // Notification: the Messages object, which alerts come from.
        let notification = object(space, "Notification", mt("Notification"), "");
        typed(space, &notification, ns.machine_tool_type(7));
        let messages = self.messages();
        ObjectBuilder::new(&messages, mt("Messages"), "Messages")
            .component_of(notification)
            .has_type_definition(ns.machine_tool_type(38))
            .event_notifier(EventNotifier::SUBSCRIBE_TO_EVENTS)
            .reference(
                ns.machine_tool_type(ALERT_TYPE),
                ReferenceTypeId::GeneratesEvent,
                ReferenceDirection::Forward,
            )
            .insert(space);
        // Equipment: mandatory, and empty (whirl keeps no tool list).
        let equipment = object(space, "Equipment", mt("Equipment"), "");
        typed(space, &equipment, ns.machine_tool_type(12));
    }

    /// A `State` (of type `type_id`) under `parent`, its `CurrentState` at `state`.
    fn state_machine(
        &self,
        space: &mut AddressSpace,
        parent: &str,
        type_id: u32,
        state: ProductionState,
    ) {
        let id = self.id(&format!("{parent}/State"));
        ObjectBuilder::new(
            &id,
            QualifiedName::new(self.ns.machine_tool, "State"),
            "State",
        )
        .component_of(self.id(parent))
        .has_type_definition(self.ns.machine_tool_type(type_id))
        .insert(space);
        VariableBuilder::new(
            &self.id(&format!("{parent}/State/CurrentState")),
            QualifiedName::new(0, "CurrentState"),
            "CurrentState",
        )
        .data_type(DataTypeId::LocalizedText)
        .value(LocalizedText::from(state.name()))
        .component_of(id)
        .has_type_definition(VariableTypeId::FiniteStateVariableType)
        .insert(space);
    }

    /// Every variable that follows the run, with its value in `values`.
    pub fn writes(&self, values: &Values) -> Vec<Write> {
        let mut writes = vec![
            (
                self.id("Monitoring/MachineTool/OperationMode"),
                Variant::Int32(values.operation_mode as i32),
            ),
            (
                self.id("Monitoring/Channel_1/ChannelState"),
                Variant::Int32(values.channel_state as i32),
            ),
            (
                self.id("Monitoring/Channel_1/FeedOverride"),
                Variant::Double(values.feed_override),
            ),
            (
                self.id("Production/ActiveProgram/Name"),
                values.program.as_str().into(),
            ),
            (
                self.id("Production/ActiveProgram/JobIdentifier"),
                values.job.as_str().into(),
            ),
            (
                self.id("Production/ActiveProgram/State/CurrentState"),
                LocalizedText::from(values.program_state.name()).into(),
            ),
            (
                self.id("Production/ActiveProgram/Line"),
                Variant::UInt32(values.line.unwrap_or(0)),
            ),
            (
                self.id("Production/ActiveProgram/Percent"),
                Variant::Double(values.percent),
            ),
            (
                self.id("Production/ProductionPlan/Job/Identifier"),
                values.job.as_str().into(),
            ),
            (
                self.id("Production/ProductionPlan/Job/RunsCompleted"),
                Variant::UInt32(values.runs_completed),
            ),
            (
                self.id("Production/ProductionPlan/Job/State/CurrentState"),
                LocalizedText::from(values.job_state.name()).into(),
            ),
        ];
        for (lamp, on) in LAMPS.iter().zip(values.lamps) {
            writes.push((
                self.id(&format!("Monitoring/Stacklight/Lamp_{lamp:?}/SignalOn")),
                Variant::Boolean(on),
            ));
        }
        writes
    }
}

/// A read-only property of `parent`.
fn property(
    space: &mut AddressSpace,
    id: NodeId,
    name: QualifiedName,
    data_type: DataTypeId,
    value: Variant,
    parent: &NodeId,
) {
    let display = name.name.to_string();
    VariableBuilder::new(&id, name, display)
        .data_type(data_type)
        .value(value)
        .property_of(parent.clone())
        .has_type_definition(VariableTypeId::PropertyType)
        .insert(space);
}

/// A read-only data variable, a component of `parent`.
fn variable(
    space: &mut AddressSpace,
    id: NodeId,
    name: QualifiedName,
    data_type: NodeId,
    value: Variant,
    parent: &NodeId,
) {
    let display = name.name.to_string();
    VariableBuilder::new(&id, name, display)
        .data_type(data_type)
        .value(value)
        .component_of(parent.clone())
        .has_type_definition(VariableTypeId::BaseDataVariableType)
        .insert(space);
}
