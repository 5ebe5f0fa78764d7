"""Adapters that plug sorojax into third-party tools (loaded only by those tools)."""
