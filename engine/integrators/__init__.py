"""Light transport: the wavefront path tracer (the report's estimator and its MIS successors) and the effect plan that decides which of its parts a scene needs."""
