"""The jobs behind the CLI verbs: each takes a config dataclass and returns a result."""
