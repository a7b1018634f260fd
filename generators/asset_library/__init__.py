"""Category modules of the procedural asset library; importing each registers its categories."""
