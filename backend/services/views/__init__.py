"""What auditors read: reports, the drawable graph, explanations, exports."""
