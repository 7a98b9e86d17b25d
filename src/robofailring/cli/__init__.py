"""The library's command-line verbs, their shared options and option groups, and the exit statuses."""
