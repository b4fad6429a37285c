"""The bridge core: routes, the adapter interface, router, statistics, QoS mapping."""
