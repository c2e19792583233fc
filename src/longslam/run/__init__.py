"""One run of a method: the engine (frames -> result and measurements), the run folder, a run in
a process of its own, its resident memory, and the one scorer used by `evaluate`, the demo,
studies and benchmarks."""
