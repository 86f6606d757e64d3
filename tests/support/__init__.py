"""Test helpers: live servers, a real Virtuoso, scenarios built with the real PyPI client."""
