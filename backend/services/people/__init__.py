"""People\x27s data: erasing one person, exporting what is held about them, and retention."""
