"""Control of the orbit: triggers, their policies, the impulsive and shooting controllers, tau_p, contact watch."""
