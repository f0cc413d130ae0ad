"""Where runs are simulated besides Ray: the executor factory, in-process and virtual executors, chunk sizes, waits, and the executors' conformance suite."""
