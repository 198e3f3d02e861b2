"""Small MCAP recordings made by the project itself (demonstrations the shipped models were trained on)."""
