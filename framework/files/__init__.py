"""Files: npz, YAML, parameter models, shipped resources and the MCAP writer and reader (docs/architecture.md).

The only part of the framework the science of the plugin families imports; it imports no Zenoh."""
