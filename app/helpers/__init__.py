"""Cross-cutting helpers the use cases share: entity tags, list pagination, tolerance grading."""
