#!/usr/bin/env python3
"""Browse and follow a whirl bridge's OPC UA for Machine Tools server with asyncua.

An independent third-party client for testing whirl's OPC UA server (src/opcua/): it shares
no code with whirl nor with async-opcua, the Rust server whirl uses. It finds the machine
as an MES would, by the standards' names (docs/opcua.md):

- the `Machines` folder by its standard NodeId (OPC 40001-1: i=1001 in the Machinery
  namespace), the machine under it by its BrowseName;
- `2:Identification`'s properties, `Monitoring`'s operation mode, stacklight and channel,
  `Production`'s active program and job, by their BrowsePaths in the MachineTool, DI and IA
  namespaces.

With --watch it then subscribes to the values' changes and, in a subscription of its
own, to AlertType events from `Notification/Messages` (in one subscription with the data
changes, async-opcua 0.19 delivered none of them after the first event), prints one line
`{"ready": true}` once subscribed, and follows
until the job's RunsCompleted reaches --until-runs, the active program's state is
--until-state (both as read) and --until-alerts alerts came (or 240 s pass: "timeout"
says so). "changes" are the values' changes as the subscription gave them by then.

It prints one JSON object (on one line) to stdout and exits 0:

    {"namespaces": [...], "machines": [...], "type_definition": {...},
     "identification": {...}, "values": {...}, "changes": {...}, "events": [...],
     "final": {...}, "timeout": false}

A connection or login the server refuses is printed as {"refused": "what it said"} and
exits 3.

With --mode sign or sign-and-encrypt it makes a client certificate in --pki (once) and
talks Basic256Sha256.

Written for asyncua 1.x and 2.x.

Usage: opcua_browse.py URL MACHINE [--user U --password P] [--mode MODE --pki DIR]
                       [--watch --until-runs N --until-alerts N --until-state NAME]
"""

import argparse
import asyncio
import json
import sys
import time
from pathlib import Path

from asyncua import Client, ua

MACHINE_TOOL = "http://opcfoundation.org/UA/MachineTool/"
DI = "http://opcfoundation.org/UA/DI/"
MACHINERY = "http://opcfoundation.org/UA/Machinery/"
IA = "http://opcfoundation.org/UA/IA/"
WHIRL = "urn:whirl:machines"
CLIENT_URI = "urn:whirl-tests:asyncua-client"


def plain(value):
    """A value as JSON: enumerations and integers as numbers, texts as text."""
    if isinstance(value, ua.LocalizedText):
        return value.Text
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    if isinstance(value, ua.NodeId):
        return value.to_string()
    return str(value)


class Follow:
    """The subscription's handler: every change of every watched value, every event. Its
    methods are coroutines, so that asyncua calls them on the loop that waits for them."""

    def __init__(self, names):
        self.names = names
        self.changes = {name: [] for name in names.values()}
        self.events = []
        self.changed = asyncio.Event()

    async def datachange_notification(self, node, val, data):
        name = self.names.get(node.nodeid)
        if name is None:
            return  # async-opcua 0.19 also sends the event item a data change: not ours
        self.changes[name].append(plain(val))
        self.changed.set()

    async def event_notification(self, event):
        fields = event.get_event_props_as_fields_dict()
        seen = {}
        for name in ("ErrorCode", "Message", "Severity", "SourceName", "ActiveState/Id",
                     "Retain", "EventType"):
            if name in fields:
                seen[name] = plain(fields[name].Value)
        self.events.append(seen)
        self.changed.set()


async def connect(args):
    client = Client(args.url, timeout=10)
    client.application_uri = CLIENT_URI
    if args.user is not None:
        client.set_user(args.user)
        client.set_password(args.password)
    if args.mode != "none":
        from asyncua.crypto.cert_gen import setup_self_signed_certificate
        from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
        from cryptography.x509.oid import ExtendedKeyUsageOID

        pki = Path(args.pki)
        pki.mkdir(parents=True, exist_ok=True)
        key, cert = pki / "client-key.pem", pki / "client-cert.der"
        await setup_self_signed_certificate(
            key, cert, CLIENT_URI, "localhost",
            [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "whirl tests client"})
        mode = {"sign": ua.MessageSecurityMode.Sign,
                "sign-and-encrypt": ua.MessageSecurityMode.SignAndEncrypt}[args.mode]
        await client.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key),
                                  mode=mode)
    await client.connect()
    return client


def parameters():
    """A subscription publishing every 50 ms, with a keep-alive each second."""
    return ua.CreateSubscriptionParameters(
        RequestedPublishingInterval=50, RequestedLifetimeCount=300,
        RequestedMaxKeepAliveCount=20, MaxNotificationsPerPublish=0,
        PublishingEnabled=True, Priority=0)


def alert_filter(alert_type, mt):
    """The fields an MES reads of an alert, AlertType's and its supertypes', of events of
    type AlertType (OfType). asyncua's default filter does not suit async-opcua 0.19: its
    where clause compares EventType with InList, which async-opcua does not evaluate for
    NodeIds (nothing passes), and it selects ConditionId with no BrowsePath, which
    async-opcua leaves out of the fields instead of answering null (the fields after it
    would shift)."""
    base = ua.NodeId(ua.ObjectIds.BaseEventType)
    condition = ua.NodeId(ua.ObjectIds.ConditionType)
    alarm = ua.NodeId(ua.ObjectIds.AlarmConditionType)
    fields = [
        (base, [(0, "EventType")]),
        (base, [(0, "Message")]),
        (base, [(0, "Severity")]),
        (base, [(0, "SourceName")]),
        (alert_type.nodeid, [(mt, "ErrorCode")]),
        (condition, [(0, "Retain")]),
        (alarm, [(0, "ActiveState"), (0, "Id")]),
    ]
    evfilter = ua.EventFilter()
    for type_id, path in fields:
        operand = ua.SimpleAttributeOperand()
        operand.TypeDefinitionId = type_id
        operand.BrowsePath = [ua.QualifiedName(name, ns) for ns, name in path]
        operand.AttributeId = ua.AttributeIds.Value
        evfilter.SelectClauses.append(operand)
    of_type = ua.ContentFilterElement()
    of_type.FilterOperator = ua.FilterOperator.OfType
    of_type.FilterOperands = [ua.LiteralOperand(Value=ua.Variant(alert_type.nodeid))]
    evfilter.WhereClause.Elements.append(of_type)
    return evfilter


async def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("machine")
    parser.add_argument("--user")
    parser.add_argument("--password")
    parser.add_argument("--mode", default="none",
                        choices=["none", "sign", "sign-and-encrypt"])
    parser.add_argument("--pki")
    parser.add_argument("--watch", action="store_true")
    parser.add_argument("--until-runs", type=int, default=0)
    parser.add_argument("--until-alerts", type=int, default=0)
    parser.add_argument("--until-state")
    args = parser.parse_args()

    try:
        client = await connect(args)
    except Exception as e:  # a refusal comes as a status, a closed connection or no endpoint
        print(json.dumps({"refused": f"{type(e).__name__}: {e}"}), flush=True)
        sys.exit(3)
    try:
        out = await follow(client, args)
    finally:
        await client.disconnect()
    print(json.dumps(out), flush=True)


async def follow(client, args):
    namespaces = await client.get_namespace_array()
    ns = {uri: namespaces.index(uri) for uri in (MACHINE_TOOL, DI, MACHINERY, IA, WHIRL)}
    mt, di, ia, whirl = ns[MACHINE_TOOL], ns[DI], ns[IA], ns[WHIRL]

    machines_folder = client.get_node(ua.NodeId(1001, ns[MACHINERY]))
    machines = await machines_folder.get_children()
    names = {}
    for node in machines:
        names[(await node.read_browse_name()).Name] = node
    machine = names[args.machine]
    type_definition = await machine.read_type_definition()

    async def child(*path):
        return await machine.get_child(list(path))

    identification = {}
    for name in ("Manufacturer", "Model", "ProductInstanceUri", "SerialNumber",
                 "SoftwareRevision"):
        try:
            node = await child(f"{di}:Identification", f"{di}:{name}")
        except ua.UaStatusCodeError:
            continue
        identification[name] = plain(await node.read_value())

    watched = {
        "OperationMode": (f"{mt}:Monitoring", f"{mt}:MachineTool", f"{mt}:OperationMode"),
        "ChannelState": (f"{mt}:Monitoring", f"{whirl}:Channel_1", f"{mt}:ChannelState"),
        "FeedOverride": (f"{mt}:Monitoring", f"{whirl}:Channel_1", f"{mt}:FeedOverride"),
        "ProgramName": (f"{mt}:Production", f"{mt}:ActiveProgram", f"{mt}:Name"),
        "ProgramState": (f"{mt}:Production", f"{mt}:ActiveProgram", f"{mt}:State",
                         "0:CurrentState"),
        "JobIdentifier": (f"{mt}:Production", f"{mt}:ProductionPlan", f"{whirl}:Job",
                          f"{mt}:Identifier"),
        "RunsCompleted": (f"{mt}:Production", f"{mt}:ProductionPlan", f"{whirl}:Job",
                          f"{mt}:RunsCompleted"),
        "JobState": (f"{mt}:Production", f"{mt}:ProductionPlan", f"{whirl}:Job",
                     f"{mt}:State", "0:CurrentState"),
    }
    for colour in ("Red", "Yellow", "Green"):
        watched[f"Lamp_{colour}"] = (f"{mt}:Monitoring", f"{mt}:Stacklight",
                                     f"{whirl}:Lamp_{colour}", f"{ia}:SignalOn")
    nodes = {name: await child(*path) for name, path in watched.items()}
    colours = {}
    for colour in ("Red", "Yellow", "Green"):
        node = await child(f"{mt}:Monitoring", f"{mt}:Stacklight", f"{whirl}:Lamp_{colour}",
                           f"{ia}:SignalColor")
        colours[colour] = plain(await node.read_value())

    async def read_all():
        return {name: plain(await node.read_value()) for name, node in nodes.items()}

    out = {
        "namespaces": namespaces,
        "machines": sorted(names),
        "type_definition": {"namespace": namespaces[type_definition.NamespaceIndex],
                            "id": type_definition.Identifier},
        "identification": identification,
        "signal_colors": colours,
        "values": await read_all(),
        "changes": {},
        "events": [],
        "timeout": False,
    }
    if not args.watch:
        return out

    handler = Follow({node.nodeid: name for name, node in nodes.items()})
    subscription = await client.create_subscription(parameters(), handler)
    await subscription.subscribe_data_change(list(nodes.values()), queuesize=1000,
                                             sampling_interval=0)
    messages = await child(f"{mt}:Notification", f"{mt}:Messages")
    alert_type = client.get_node(ua.NodeId(39, mt))
    alerts = await client.create_subscription(parameters(), handler)  # of its own: see above
    await alerts.subscribe_events(messages, alert_type,
                                        evfilter=alert_filter(alert_type, mt),
                                        queuesize=1000)
    print(json.dumps({"ready": True}), flush=True)

    async def done():
        # The values as read (a subscriber may get the last change late: docs/opcua.md),
        # the alerts as they came.
        runs = await nodes["RunsCompleted"].read_value()
        state = plain(await nodes["ProgramState"].read_value())
        return (runs >= args.until_runs
                and len(handler.events) >= args.until_alerts
                and (args.until_state is None or state == args.until_state))

    deadline = time.monotonic() + 240
    while not await done():
        left = deadline - time.monotonic()
        if left <= 0:
            out["timeout"] = True
            break
        handler.changed.clear()
        try:
            await asyncio.wait_for(handler.changed.wait(), min(left, 0.2))
        except asyncio.TimeoutError:
            pass
    await subscription.delete()
    await alerts.delete()
    out["changes"] = handler.changes
    out["events"] = handler.events
    out["final"] = await read_all()
    return out


if __name__ == "__main__":
    asyncio.run(main())
