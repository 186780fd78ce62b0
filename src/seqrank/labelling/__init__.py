"""The labelling page: people answer the schemes' questions (online, offline, study)."""
