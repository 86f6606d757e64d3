"""Reports kept current from what each write added, so they are served from rows instead of evaluated."""
