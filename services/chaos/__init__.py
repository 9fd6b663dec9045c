"""The standing fault matrix (`tidelink chaos`): real launches, one fault each, judged."""
