"""Safety monitor: clearances, ways out of contact, stepping aside, plans flown, fleet intents."""
