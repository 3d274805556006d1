"""mrta-drake: test multi-robot task allocation with planning and control in a Drake hospital."""
