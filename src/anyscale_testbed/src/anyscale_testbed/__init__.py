"""AnyScale test bed (evaluation only): two scales on one machine, its link shaping and
recorders."""
