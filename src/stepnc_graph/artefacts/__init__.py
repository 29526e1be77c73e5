"""The generated artefacts: building and checking them (`ontology build`), their statistics."""
