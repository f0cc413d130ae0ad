"""Jobs that simulate for one command in a campaign directory: quantification (one campaign per side), planning, falsify, re-runs; their set-up, signals and resource checks."""
