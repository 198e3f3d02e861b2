"""Old framework module paths keep working for one release, with a DeprecationWarning (docs/architecture.md).

Every module that moved in the grouping of ``framework/`` (issue 36) is imported by its old path,
and every public name it had is the same object as at its new path.
"""

from __future__ import annotations

import importlib
import sys

import pytest

from handflow.framework import MOVED

# the public names of each moved module before the move (git show 740a82d:framework/<module>.py)
OLD_NAMES = {
    "npz_files": "NpzFileError building npz_metadata npz_names read_npz",
    "yaml_files": "M Problem YamlFileError line_index line_of load_model parse pydantic_problems",
    "params": "StrictModel",
    "resources": "shipped shipped_recording",
    "recording": "DEFAULT_QOS ENCODINGS FOXGLOVE_IMAGE_SUFFIX FOXGLOVE_RAW_IMAGE_SCHEMA GraphRecorder MAX_ATTACHED_FILE_BYTES MESSAGE_ENCODING McapWriter ReadReport RecordedMessage RecordingError SCHEMA_ENCODING TYPE_KEY TopicFilter VIEW_KEY WireHeader graph_provenance iter_recording log peek_header read_messages read_report",
    "graph": "FoxgloveSettings Graph GraphError GraphSpec NodeSpec RecordSpec ResolvedNode RestartPolicy Ros2Settings TlsSettings UsrPwdSettings ZenohSettings graph_path is_loopback_endpoint known_plugins load_graph read_graph_text shipped_graphs validate_file",
    "transport": "EndpointInUse PREFIX clock_key events_key free_tcp_port hub_endpoint_for open_client open_hub open_node_session split_key start_key topic_key",
    "launcher": "LOG_TAIL Launcher STOP_GRACE_S Unit log plan_units run_graph",
    "runner": "GroupRuntime HEARTBEAT_S NodeContext ORPHAN_GRACE_S ORPHAN_POLL_S START_WAIT_S SeqState log main",
    "zygote": "ForkedProcess MAX_REQUEST REAP_S SPAWN_TIMEOUT_S Zygote main serve start_unless_disabled",
    "discovery": "DiscoveryError RunInfo add_auth_arguments find_run join live_runs log remove_run_file run_dir write_run_file",
    "drops": "DropLedger LOG_INTERVAL_S",
    "forwarding": "snapshot unchanged",
    "wakeup": "wakeup_queue",
    "ros2.bridge": "Ros2Bridge log",
    "replay": "GraphWatcher LockstepReplayer ReplayError ReplayPlan ReplayStats TimedReplayer external_inputs log remap_key wait_matching",
    "monitor": "ALIVE_S Monitor NodeHealth TopicStats WINDOW_S render summarize",
    "foxglove_bridge": "BridgeError FoxgloveBridge PortInUse log start_bridge",
    "access": "ALL_MESSAGES access_control certificate_dir tls_settings",
    "certs": "CA_CERT CA_KEY CertError EXTRA_HINT add_host check_host_files host_files init_ca",
    "credentials": "Credentials CredentialsError FORMAT graph_credentials log parse_credentials read_credentials usrpwd_settings write_dictionary",
    "testing": "HarnessContext NodeHarness check_publish",
    "fuzzing": "BYTE_OPS EXTREMES JSON_OPS Mutation OPS malformed_payloads mutate random_mutations sample_messages",
}


def test_every_moved_module_is_listed():
    assert set(OLD_NAMES) == set(MOVED)


@pytest.mark.parametrize("old", sorted(OLD_NAMES))
def test_old_path_warns_and_gives_the_new_objects(old, monkeypatch):
    old_path = f"handflow.framework.{old}"
    new_paths = [f"handflow.framework.{m}" for m in MOVED[old]]
    monkeypatch.delitem(sys.modules, old_path, raising=False)
    with pytest.warns(DeprecationWarning, match=new_paths[0].replace(".", r"\.")):
        module = importlib.import_module(old_path)
    homes = [importlib.import_module(p) for p in new_paths]
    if len(homes) == 1:
        assert module is homes[0]
    for name in OLD_NAMES[old].split():
        home = next((h for h in homes if name in vars(h)), None)
        assert home is not None, f"{old_path}.{name} has no new home"
        assert getattr(module, name) is getattr(home, name)
