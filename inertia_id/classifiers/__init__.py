"""Every classifier kind, one family: the shared base, the registry and one module per kind."""
