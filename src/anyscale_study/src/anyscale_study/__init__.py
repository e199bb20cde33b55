"""The paper's Fig. 7 simulation study over anyscale_core's allocators; evaluation only."""
