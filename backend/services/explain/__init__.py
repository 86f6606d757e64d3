"""The causal story around one message, activity, emotion or state."""
