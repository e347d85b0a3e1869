"""The input contract: the task records (schema) and their loading from YAML (load)."""
