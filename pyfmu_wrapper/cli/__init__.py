"""The console entry points: each command's main, its arguments and its exit statuses."""
