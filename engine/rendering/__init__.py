"""A frame as work: tiles and work units, the render session (a scene prepared once, units rendered and merged), stopping rules, the render-time estimate, the memory check."""
