"""YAML graph files: pydantic models, loading with line numbers, and validation (docs/architecture.md).

A graph names nodes, the plugin each runs, its parameters (validated by the plugin's own params
model) and which outputs feed which inputs (``inputs: {port: node/output}``); plus Zenoh settings,
topics fed from outside (``external``), process groups, hosts, restart policies and recording.
:func:`load_graph` returns a :class:`Graph` or raises :class:`GraphError` listing every problem as
``file:line: message`` with what to change.  Feedback loops are legal.
"""

from __future__ import annotations

import re
from collections.abc import Collection
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field, ValidationError, field_validator

from ..files.inputs import node_input_problems
from ..files.params import StrictModel
from ..files.yaml import Problem, YamlFileError, line_of, parse, pydantic_problems
from ..messages import Message, message_types
from ..network.settings import TransportSettings, UsrPwdSettings, ZenohSettings, is_loopback_endpoint
from ..plugin import Node
from ..registry import PluginError, load_plugin, plugin_entries
from ..ros2.rmw_zenoh import check_name

_ID = re.compile(r"^[A-Za-z0-9_\-]+$")


class RestartPolicy(StrictModel):
    """Supervision of a node's process (docs/pipelines.md): restarted on failure by default."""

    policy: Literal["never", "on-failure"] = "on-failure"
    max_restarts: int = Field(5, ge=0, description="more failures than this within window_s is a crash loop")
    backoff_s: float = Field(0.5, ge=0, description="first restart delay, doubled per recent failure")
    max_backoff_s: float = Field(
        2.0, ge=0, description="cap of the restart delay (5 restarts then take 7.5 s: a crash loop shows within 10 s)"
    )
    window_s: float = Field(60.0, gt=0, description="failures older than this are forgotten")


class NodeSpec(StrictModel):
    id: str
    plugin: str
    params: dict[str, Any] = Field(default_factory=dict)
    inputs: dict[str, str] = Field(default_factory=dict)
    group: str | None = Field(None, description="nodes of one group share a process")
    host: str | None = Field(None, description="run only by `handflow run --host NAME`")
    restart: RestartPolicy = Field(default_factory=RestartPolicy)

    @field_validator("id")
    @classmethod
    def _id_chars(cls, v: str) -> str:
        if not _ID.match(v):
            raise ValueError("node id may contain letters, digits, '_' and '-' only")
        return v


class RecordSpec(StrictModel):
    path: str | None = Field(None, description="MCAP file; `handflow run --record` overrides it")
    topics: list[str] = Field(default_factory=lambda: ["**"], description="globs over node/port, e.g. 'glove/*'")


class FoxgloveSettings(StrictModel):
    """Live view: a Foxglove WebSocket server started by the launcher, streaming every topic."""

    host: str = "127.0.0.1"
    port: int = Field(8765, ge=0, le=65535, description="0 picks a free port")


class Ros2Settings(StrictModel):
    """Live ROS 2 interop: selected topics republished as rmw_zenoh does it (docs/ros2.md)."""

    domain_id: int = Field(0, ge=0, le=232, description="ROS_DOMAIN_ID of the ROS 2 system")
    node_name: str | None = Field(None, description="ROS 2 node name; default: the graph name ('-' → '_')")
    namespace: str = Field("/", description="ROS 2 namespace of that node")
    publish: list[str] | dict[str, str] = Field(
        default_factory=list,
        description="node/port topics to publish; as a mapping node/port → ROS 2 topic name, else /<node>/<port>",
    )
    depth: int = Field(10, ge=1, description="history depth announced in the QoS of each publisher")

    def topics(self) -> dict[str, str]:
        """node/port → ROS 2 topic name."""
        if isinstance(self.publish, dict):
            return dict(self.publish)
        return {src: "/" + src.replace("-", "_") for src in self.publish}

    def ros_node_name(self, graph_name: str) -> str:
        return self.node_name or graph_name.replace("-", "_")


class StatusSpec(StrictModel):
    """A status line in the terminal of `handflow run`: one field of one topic (docs/pipelines.md)."""

    topic: str = Field(description="node/port shown, e.g. segmenter/labels")
    field: str = Field(description="the message field shown (a str, int, float or bool), e.g. label")
    min_interval_s: float = Field(
        1.0, ge=0, description="a line when the value changed, at most one per this many seconds"
    )


class GraphSpec(StrictModel):
    name: str
    description: str = ""
    zenoh: ZenohSettings = Field(default_factory=ZenohSettings)
    transport: TransportSettings = Field(default_factory=TransportSettings)
    external: dict[str, str] = Field(default_factory=dict, description="node/port → message type fed from outside")
    nodes: list[NodeSpec]
    record: RecordSpec | None = None
    foxglove: FoxgloveSettings | None = None
    ros2: Ros2Settings | None = None
    status: StatusSpec | None = None

    @field_validator("name")
    @classmethod
    def _name_chars(cls, v: str) -> str:
        if not _ID.match(v):
            raise ValueError("graph name may contain letters, digits, '_' and '-' only")
        return v


class GraphError(YamlFileError):
    """A graph file with problems; ``str()`` lists them as ``file:line: message``."""


@dataclass
class ResolvedNode:
    spec: NodeSpec
    cls: type[Node]
    params: BaseModel
    line: int = 1  # of the node's entry in the graph file, for reports at run time


@dataclass
class Graph:
    """A validated graph: the spec, each node's class and validated params, where the file lives."""

    spec: GraphSpec
    path: Path
    nodes: dict[str, ResolvedNode] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def base_dir(self) -> Path:
        return self.path.parent

    def source_type(self, source: str) -> type[Message] | None:
        """Message type published at ``node/port`` (a graph node or an external topic)."""
        node_id, _, port = source.partition("/")
        if node_id in self.nodes:
            rn = self.nodes[node_id]
            return rn.cls.output_types(rn.params).get(port)
        name = self.spec.external.get(source)
        return _message_type(name) if name else None

    def subscribers(self, source: str) -> list[tuple[str, str]]:
        """(node id, input port) pairs fed by ``node/port``."""
        return [(nid, port) for nid, rn in self.nodes.items() for port, src in rn.spec.inputs.items() if src == source]


def _message_type(name: str) -> type[Message] | None:
    types = message_types()
    return types.get(name) or types.get(f"handflow.{name}")


# ----------------------------------------------------------------------------------------------
# Loading and validation
# ----------------------------------------------------------------------------------------------
def read_graph_text(
    text: str, path: Path, only: Collection[str] | None = None, preflight: bool = False, host: str | None = None
) -> tuple[Graph | None, list[Problem]]:
    """Parse and validate graph YAML; returns the graph (None if unusable) and all problems in file
    order, one mistake hiding no other (docs/pipelines.md, "The graph file").

    With ``only``, plugin classes are loaded and checked for those node ids alone (a node process
    of an already validated graph imports just its own plugins; docs/architecture.md).  With
    ``preflight``, the inputs of the nodes ``handflow run --host HOST`` would start (files, folders,
    devices, extras; :mod:`.inputs`) are checked too (docs/pipelines.md, "Inputs").
    """
    parsed = parse(text)
    if isinstance(parsed, Problem):
        return None, [parsed]
    data, lines = parsed
    if not isinstance(data, dict):
        return None, [Problem(1, "a graph file must be a YAML mapping with 'name' and 'nodes'")]
    spec, index, problems = _read_spec(data, lines)
    if spec is None:
        return None, _in_file_order(problems)

    graph = Graph(spec, path)
    classes: dict[str, type[Node]] = {}  # nodes whose plugin loaded, their params valid or not
    seen: dict[str, int] = {}
    for i, ns in zip(index, spec.nodes):
        if ns.id in seen:
            problems.append(
                Problem(
                    line_of(lines, ("nodes", i, "id")),
                    f"duplicate node id '{ns.id}' (first used on line {seen[ns.id]}); give each node a unique id",
                )
            )
            continue
        seen[ns.id] = line_of(lines, ("nodes", i, "id"))
        if only is not None and ns.id not in only:
            continue
        try:
            cls = classes[ns.id] = load_plugin(ns.plugin, path.parent)
        except PluginError as exc:
            problems.append(Problem(line_of(lines, ("nodes", i, "plugin")), str(exc)))
            continue
        try:
            params = cls.Params.model_validate(ns.params)
        except ValidationError as exc:
            problems += pydantic_problems(exc, lines, ("nodes", i, "params"), f"node '{ns.id}' param ")
            failed = {err["loc"][0] for err in exc.errors() if err["loc"]}
            params = {k: v for k, v in ns.params.items() if k not in failed}  # the rest is still checked
        else:
            graph.nodes[ns.id] = ResolvedNode(ns, cls, params, seen[ns.id])
        if preflight and ns.host == host:
            for loc, message in node_input_problems(cls, params, path.parent):
                at = ("nodes", i, "params", *loc) if loc else ("nodes", i, "plugin")
                problems.append(Problem(line_of(lines, at), f"node '{ns.id}' ({ns.plugin}): {message}"))

    for topic, tname in spec.external.items():
        if _message_type(tname) is None:
            problems.append(
                Problem(
                    line_of(lines, ("external", topic)),
                    f"external topic '{topic}': unknown message type '{tname}'; known: {', '.join(sorted(message_types()))}",
                )
            )

    problems += _zenoh_problems(spec, lines)
    if spec.zenoh.usrpwd is not None:
        problems += _usrpwd_problems(spec.zenoh.usrpwd, path, lines)
    if spec.ros2 is not None:
        problems += _ros2_problems(graph, spec.ros2, lines)
    if spec.status is not None:
        problems += _status_problems(graph, spec.status, lines)

    checked: set[str] = set()
    for i, ns in zip(index, spec.nodes):
        if ns.id not in classes or ns.id in checked:
            continue  # an unknown plugin, a duplicate id or a node this process does not load
        checked.add(ns.id)
        for port, source in ns.inputs.items():
            line = line_of(lines, ("nodes", i, "inputs", port))
            problems += _input_problems(graph, classes, ns, port, source, line)
    return (graph if not problems else None), _in_file_order(problems)


def _in_file_order(problems: list[Problem]) -> list[Problem]:
    return sorted(problems, key=lambda p: p.line)


def _read_spec(data: dict, lines: dict) -> tuple[GraphSpec | None, list[int], list[Problem]]:
    """The graph's spec with the nodes that passed their own checks, their indices in the file's node
    list, and the problems of the others and of the top-level fields; a top-level field that fails is
    left out, so the nodes are still checked (None: the spec fails without it, e.g. no 'name')."""
    problems: list[Problem] = []
    index: list[int] = []
    nodes = data.get("nodes")
    if isinstance(nodes, list):
        valid = []
        for i, raw in enumerate(nodes):
            try:
                valid.append(NodeSpec.model_validate(raw))
                index.append(i)
            except ValidationError as exc:
                problems += pydantic_problems(exc, lines, ("nodes", i), f"nodes.{i}.")
        data = {**data, "nodes": valid}
    try:
        return GraphSpec.model_validate(data), index, problems
    except ValidationError as exc:
        problems += pydantic_problems(exc, lines)
        failed = {err["loc"][0] for err in exc.errors() if err["loc"]}
    try:
        return GraphSpec.model_validate({k: v for k, v in data.items() if k not in failed}), index, problems
    except ValidationError:
        return None, [], problems


def _zenoh_problems(spec: GraphSpec, lines) -> list[Problem]:
    """Plain endpoints beyond loopback need TLS or an explicit ``insecure: true`` (docs/security.md)."""
    z = spec.zenoh
    problems = []
    for key in ("listen", "connect"):
        for i, ep in enumerate(getattr(z, key)):
            plain = not ep.startswith(("tls/", "quic/"))
            if z.tls is not None and plain and not is_loopback_endpoint(ep):
                problems.append(
                    Problem(
                        line_of(lines, ("zenoh", key, i)),
                        f"zenoh {key} endpoint '{ep}' is not TLS although 'zenoh.tls' is set; use tls/{ep.partition('/')[2]}",
                    )
                )
            elif z.tls is None and plain and not z.insecure and not is_loopback_endpoint(ep):
                risk = (
                    "user names and passwords of 'usrpwd' travel in clear text and anyone on the network "
                    "could read every topic"
                    if z.usrpwd is not None
                    else "any peer that reaches it could join, read and publish on every topic"
                )
                problems.append(
                    Problem(
                        line_of(lines, ("zenoh", key, i)),
                        f"zenoh {key} endpoint '{ep}' reaches beyond this machine without TLS: {risk}. Create certificates "
                        f"(`handflow certs init certs && handflow certs add-host certs NAME`), set "
                        f"'zenoh: {{tls: {{certs: certs}}}}' and use tls/ endpoints, or write 'insecure: true' "
                        f"under 'zenoh:' to accept the risk (docs/security.md)",
                    )
                )
            elif not plain and z.tls is None:
                problems.append(
                    Problem(
                        line_of(lines, ("zenoh", key, i)),
                        f"zenoh {key} endpoint '{ep}' needs certificates: add 'tls: {{certs: DIR}}' under 'zenoh:'",
                    )
                )
    if z.tls is not None:
        for topic in z.tls.publishers:
            if topic not in spec.external:
                problems.append(
                    Problem(
                        line_of(lines, ("zenoh", "tls", "publishers", topic)),
                        f"zenoh.tls.publishers names '{topic}', which is not an 'external' topic of this graph",
                    )
                )
    return problems


def _usrpwd_problems(usrpwd: UsrPwdSettings, path: Path, lines) -> list[Problem]:
    """The credentials file must exist, parse and name the configured user (docs/security.md)."""
    from ..security.credentials import CredentialsError, read_credentials

    try:
        creds = read_credentials(path.parent / usrpwd.credentials)
        if usrpwd.user is not None:
            creds.login(usrpwd.user)
    except CredentialsError as exc:
        return [Problem(line_of(lines, ("zenoh", "usrpwd", "credentials")), f"zenoh.usrpwd.credentials: {exc}")]
    return []


def _ros2_problems(graph: Graph, ros2: Ros2Settings, lines: dict) -> list[Problem]:
    problems = []
    declared = {n.id for n in graph.spec.nodes}
    for source, topic in ros2.topics().items():
        node_id = source.partition("/")[0]
        if node_id in declared and node_id not in graph.nodes:
            continue  # not loaded here (another process's node, or failed its own checks)
        line = line_of(lines, ("ros2", "publish", source) if isinstance(ros2.publish, dict) else ("ros2", "publish"))
        if graph.source_type(source) is None and source.partition("/")[0] in graph.nodes:
            problems.append(Problem(line, f"ros2.publish: '{source}' is not an output of this graph; use node/port"))
        elif graph.source_type(source) is None:
            problems.append(
                Problem(line, f"ros2.publish: no node '{source.partition('/')[0]}' in this graph; use node/port")
            )
        try:
            check_name(topic)
        except ValueError as exc:
            problems.append(Problem(line, f"ros2.publish '{source}': {exc}"))
    return problems


def _status_problems(graph: Graph, status: StatusSpec, lines: dict) -> list[Problem]:
    """The status topic must be an output of the graph, its field a scalar field of that type."""
    node_id = status.topic.partition("/")[0]
    if node_id in {n.id for n in graph.spec.nodes} and node_id not in graph.nodes:
        return []  # not loaded here (another process's node, or failed its own checks)
    mtype = graph.source_type(status.topic)
    if mtype is None:
        return [
            Problem(
                line_of(lines, ("status", "topic")),
                f"status.topic '{status.topic}' is not an output of this graph; use node/port",
            )
        ]
    scalars = [f.name for f in fields(mtype) if f.type in ("str", "int", "float", "bool")]
    if status.field not in scalars:
        return [
            Problem(
                line_of(lines, ("status", "field")),
                f"status.field '{status.field}': {mtype.TYPE} has no such scalar field; choose one of {', '.join(scalars) or 'none'}",
            )
        ]
    return []


def _input_problems(
    graph: Graph, classes: dict[str, type[Node]], ns: NodeSpec, port: str, source: str, line: int
) -> list[Problem]:
    """What is wrong with input ``port`` of node ``ns`` reading ``source``; the message types are
    compared where both nodes' params are valid, the port names wherever their plugins loaded."""
    nid, cls = ns.id, classes[ns.id]
    if port not in cls.inputs:
        return [
            Problem(
                line,
                f"node '{nid}' ({ns.plugin}) has no input port '{port}'; its inputs: {', '.join(cls.inputs) or 'none'}",
            )
        ]
    src_node, sep, src_port = source.partition("/")
    if not sep or not src_port:
        return [Problem(line, f"node '{nid}' input '{port}': source must be 'node/port', got '{source}'")]
    if src_node not in classes and source not in graph.spec.external:
        if any(n.id == src_node for n in graph.spec.nodes):
            return []  # the source node exists but its plugin did not load (reported there)
        return [
            Problem(
                line,
                f"node '{nid}' input '{port}' reads from missing node '{src_node}'; "
                f"existing nodes: {', '.join(n.id for n in graph.spec.nodes)} (or declare '{source}' under 'external:')",
            )
        ]
    if src_node in classes and src_port not in classes[src_node].outputs:
        outs = classes[src_node].outputs
        return [
            Problem(
                line,
                f"node '{nid}' input '{port}': node '{src_node}' has no output '{src_port}'; its outputs: {', '.join(outs) or 'none'}",
            )
        ]
    out_type = graph.source_type(source)
    rn = graph.nodes.get(nid)
    if out_type is None or rn is None:
        return []  # a node whose params failed (reported there), or an external topic of an unknown type
    in_type = rn.cls.input_types(rn.params)[port]
    if not issubclass(out_type, in_type):
        return [
            Problem(
                line,
                f"node '{nid}' input '{port}' expects {in_type.TYPE or 'any message'} but '{source}' publishes {out_type.TYPE}; connect a matching output",
            )
        ]
    return []


def graph_path(argument: str | Path) -> Path:
    """A graph argument as a file: a path, or the name of a shipped graph (no ``/``, no ``.yaml`` suffix).

    ``handflow run demo`` runs the ``demo.yaml`` shipped in ``handflow.configs``
    (docs/pipelines.md); anything that looks like a path is taken as one.
    """
    text = str(argument)
    if "/" in text or text.endswith((".yaml", ".yml")) or Path(text).exists():
        return Path(text)
    from ..files.resources import shipped

    return shipped(f"{text}.yaml")


def shipped_graphs() -> list[str]:
    """Names of the graphs shipped with the package."""
    from ..files.resources import shipped

    return sorted(p.stem for p in shipped().glob("*.yaml"))


def validate_file(
    path: str | Path, only: Collection[str] | None = None, preflight: bool = False, host: str | None = None
) -> tuple[Graph | None, list[Problem]]:
    path = graph_path(path)
    if not path.exists() and path.parent == graph_path("x").parent:
        return None, [Problem(1, f"no shipped graph '{path.stem}'; shipped graphs: {', '.join(shipped_graphs())}")]
    try:
        text = path.read_text()
    except OSError as exc:
        return None, [Problem(1, f"cannot read graph file: {exc.strerror}")]
    return read_graph_text(text, path.resolve(), only, preflight, host)


def load_graph(
    path: str | Path,
    only: Collection[str] | None = None,
    preflight: bool = False,
    host: str | None = None,
    text: str | None = None,
) -> Graph:
    """A validated :class:`Graph` (plugins of the ``only`` node ids, or all; inputs checked with
    ``preflight``, see :func:`read_graph_text`), or :class:`GraphError`.  With ``text``, that is the
    file's content (a version of it kept while the file changes, docs/tuning.md)."""
    if text is not None:
        graph, problems = read_graph_text(text, graph_path(path).resolve(), only, preflight, host)
    else:
        graph, problems = validate_file(path, only, preflight, host)
    if problems or graph is None:
        raise GraphError(graph_path(path), problems)
    return graph


def known_plugins() -> list[str]:
    return sorted(plugin_entries())
