"""The Ray runtime: the Ray executor, its actor pool, starting or joining Ray, and watching it."""
