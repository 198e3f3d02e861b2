"""``lsl.inlet`` / ``lsl.outlet``: Lab Streaming Layer streams into and out of a graph (docs/lsl.md).

Uses ``mne-lsl``, whose Linux wheels bundle liblsl (optional extra: ``pip install 'handflow[lsl]'``).
The inlet resolves one stream, pulls what arrived in ``tick()`` and publishes one
:class:`~handflow.framework.messages.Array` per sample (channel names from the stream's
description), stamped with the sender's time mapped to this host's wall clock by liblsl's clock
synchronisation (``clock.py``).  The outlet sends each Array on its input as one sample.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
from pydantic import Field, model_validator

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array, MessageError
from handflow.framework.plugin import Node

from .clock import lsl_to_stamps, stamp_to_lsl, wall_minus_lsl_ns

REQUIRES = {"mne_lsl": "lsl"}  # checked by `handflow validate` (docs/pipelines.md, "Inputs")
EXTRA_HINT = "the lsl plugins need the 'lsl' extra (mne-lsl, which bundles liblsl): pip install 'handflow[lsl]'"


def lsl_module() -> Any:
    """``mne_lsl.lsl``, or an ImportError naming the extra."""
    try:
        return importlib.import_module("mne_lsl.lsl")
    except ImportError as exc:
        raise ImportError(f"{EXTRA_HINT} ({exc})") from None


class InletParams(StrictModel):
    name: str | None = Field(None, description="stream name to resolve")
    type: str | None = Field(None, description="stream type to resolve, e.g. EMG, EEG, Mocap")
    source_id: str | None = Field(None, description="stream source id to resolve (the most specific)")
    resolve_timeout_s: float = Field(10.0, gt=0, description="how long setup waits for the stream")
    rate_hz: float = Field(200.0, gt=0, description="how often arrived samples are pulled and published")
    dejitter: bool = Field(False, description="smooth timestamps of regular-rate streams (liblsl dejitter)")

    @model_validator(mode="after")
    def _some_filter(self) -> InletParams:
        if not (self.name or self.type or self.source_id):
            raise ValueError("give at least one of name, type, source_id to find the stream")
        return self


class OutletParams(StrictModel):
    name: str = Field(description="stream name")
    type: str = Field("handflow", description="stream type, e.g. EMG, Mocap")
    source_id: str = Field("", description="unique source id (lets receivers reconnect after a restart)")
    sfreq: float = Field(0.0, ge=0, description="nominal rate in Hz; 0 = irregular")
    channels: int = Field(0, ge=0, description="channels per sample; 0 = the size of the first message")


class LslInlet(Node):
    """Receive an LSL stream: one Array per sample on 'out', stamps clock-corrected to this host."""

    Params = InletParams
    outputs = {"out": Array}
    requires = REQUIRES

    def setup(self) -> None:
        lsl, p = lsl_module(), self.params
        filters = {k: v for k, v in {"name": p.name, "stype": p.type, "source_id": p.source_id}.items() if v}
        found = lsl.resolve_streams(timeout=p.resolve_timeout_s, **filters)
        if not found:
            raise RuntimeError(f"no LSL stream with {filters} found within {p.resolve_timeout_s:g} s")
        flags = ("clocksync", "dejitter") if p.dejitter else ("clocksync",)
        self.inlet = lsl.StreamInlet(found[0], processing_flags=flags)
        self.inlet.open_stream(timeout=p.resolve_timeout_s)
        info = self.inlet.get_sinfo()
        if np.dtype(info.dtype).kind not in "biuf":
            raise RuntimeError(f"LSL stream '{info.name}' carries {info.dtype} values; only numeric streams are read")
        names = info.get_channel_names()
        self.names = list(names) if names and all(names) else [f"ch{i}" for i in range(info.n_channels)]
        self.local_clock = lsl.local_clock
        self.ctx.log.info(
            "LSL stream '%s' (%s, %d channels, %g Hz)", info.name, info.stype, info.n_channels, info.sfreq
        )

    def tick(self) -> None:
        data, timestamps = self.inlet.pull_chunk(timeout=0.0)
        if len(timestamps) == 0:
            return
        stamps = lsl_to_stamps(timestamps, wall_minus_lsl_ns(self.local_clock))
        for row, stamp in zip(np.asarray(data, np.float64), stamps.tolist()):
            if not np.all(np.isfinite(row)):
                self.ctx.log.warning("dropped an LSL sample with non-finite values")
                continue
            self.ctx.publish("out", Array(data=row, names=self.names), stamp_ns=stamp)

    def teardown(self) -> None:
        if hasattr(self, "inlet"):
            self.inlet.close_stream()


class LslOutlet(Node):
    """Send each Array arriving on 'in' as one sample of an LSL stream, stamped with the message stamp."""

    Params = OutletParams
    inputs = {"in": Array}
    requires = REQUIRES

    def setup(self) -> None:
        self.lsl = lsl_module()
        self.outlet = None
        if self.params.channels:
            self._open(self.params.channels, [])

    def _open(self, n: int, names: list[str]) -> None:
        p = self.params
        info = self.lsl.StreamInfo(p.name, p.type, n, p.sfreq, "float64", p.source_id)
        if names:
            info.set_channel_names(names)
        self.outlet = self.lsl.StreamOutlet(info)
        self.channels = n

    def on_message(self, port: str, msg: Array) -> None:
        if self.outlet is None:
            self._open(msg.data.size, list(msg.names))
        if msg.data.size != self.channels:
            raise MessageError(
                f"LSL stream '{self.params.name}' has {self.channels} channels, got {msg.data.size} values"
            )
        ts = stamp_to_lsl(msg.header.stamp_ns, wall_minus_lsl_ns(self.lsl.local_clock))
        self.outlet.push_sample(np.ascontiguousarray(msg.data, np.float64), timestamp=ts)

    def teardown(self) -> None:
        self.outlet = None
