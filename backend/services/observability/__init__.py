"""What the server tells operators' tools: Prometheus metrics, webhooks for findings, OpenTelemetry traces."""
