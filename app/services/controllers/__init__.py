"""What the service says to robot controllers and hears back: an active TCP deployed and
read back (deployments), touches captured (capture), the reconcile (reconcile; settling
settles an unverified deployment; watcher runs the rounds), and each tool's controller
state (states).
"""
