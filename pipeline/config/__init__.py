"""The typed config of every stage (``conf/<stage>.yaml``): its schema, one module a stage."""
