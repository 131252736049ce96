"""Motion: the desired quartic path, the sinusoidal joint trajectory, and the trajectory families."""
