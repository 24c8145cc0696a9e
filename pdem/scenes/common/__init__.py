"""What the scenes share: the preparation of a ballast bed in stages (`pdem.scenes.common.preparation`)."""
