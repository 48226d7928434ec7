// peridot.live: a run's live state over Cyclone DDS (C API), loopback-only by
// default. See docs/live.md for topics, QoS and network configuration.
export module peridot.live;
import peridot.std;
export import :options;
export import :publisher;
export import :subscriber;
