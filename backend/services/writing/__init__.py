"""The write path: the journal (the source of truth), the applier that projects it into the store, and the
`WritePath` that owns them with the views' keeper and the leaderships deciding which process does what."""
