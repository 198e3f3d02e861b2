"""Lab Streaming Layer streams into and out of a graph (optional extra ``lsl``; docs/lsl.md)."""
