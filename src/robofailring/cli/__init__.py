"""The library's command-line verbs, their shared options and the exit statuses."""
