"""web: a live page of what cbgo sees and decides (hands, scene, gestures, intents, plans)."""
