"""Issue 50: the learned backends (``flux``, ``sam``, ``depth_anything``) run through the
stages' code on small models built here and saved with ``save_pretrained``, the layout of a
user's weights folder. Nothing is downloaded; the models are random, so the images are noise
and the masks and depths arbitrary: these tests prove the plumbing (loaders, call signatures,
shapes, dtypes, schemas, what is scored), not the models. A change of the libraries' API
that breaks a loader or a call fails here."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from locoman.artifacts import read_json, read_npz
from locoman.config.perception import (
    CloudsCfg,
    DepthErrorCfg,
    FluxCfg,
    GenerateCfg,
    MasksCfg,
    SimViewCfg,
    TorchCfg,
)
from locoman.errors import ConfigError, ModelError
from locoman.perception.clouds import clouds_scenario
from locoman.perception.generate import generate_scenario
from locoman.perception.io import (
    CLOUDS,
    GROUND_TRUTH_DIR,
    MASKS,
    PROMPTS,
    PROMPTS_FILE,
    SUBTASKS_DIR,
    read_png,
    subtask_dir,
)
from locoman.perception.masks import masks_scenario
from locoman.perception.weights import torch_runtime

torch = pytest.importorskip("torch", reason="the learned extra: pip install -e .[learned]")
diffusers = pytest.importorskip("diffusers", reason="the learned extra")
transformers = pytest.importorskip("transformers", reason="the learned extra")

LETTERS = "abcdefghijklmnopqrstuvwxyz"
SIZE = 64  # [px] flux's images: the smallest the config allows, a few seconds on the CPU
RENDERED = 192  # [px] the render backend's: tiny's box fills enough pixels at this size


def tiny_flux(folder: Path) -> Path:
    """A FluxPipeline of one double and one single transformer block, a one-level VAE,
    CLIP and T5 text encoders of one layer with a letters-only vocabulary."""
    torch.manual_seed(0)
    vocab = {"<|startoftext|>": 0, "<|endoftext|>": 1}
    for c in LETTERS:
        vocab[c] = len(vocab)
        vocab[c + "</w>"] = len(vocab)
    folder.mkdir(parents=True)
    (folder / "vocab.json").write_text(json.dumps(vocab))
    (folder / "merges.txt").write_text("#version: 0.2\n")
    clip_tokenizer = transformers.CLIPTokenizer(
        str(folder / "vocab.json"), str(folder / "merges.txt"), model_max_length=77
    )
    t5_vocab = [("<pad>", 0.0), ("</s>", 0.0), ("<unk>", 0.0), ("\u2581", -2.0)]
    t5_vocab += [(c, -3.0) for c in LETTERS]
    t5_tokenizer = transformers.T5TokenizerFast(vocab=t5_vocab, extra_ids=0)
    clip = transformers.CLIPTextModel(
        transformers.CLIPTextConfig(
            bos_token_id=0,
            eos_token_id=1,
            pad_token_id=1,
            vocab_size=len(vocab),
            hidden_size=32,
            intermediate_size=37,
            num_attention_heads=4,
            num_hidden_layers=1,
            projection_dim=32,
        )
    )
    t5 = transformers.T5EncoderModel(
        transformers.T5Config(
            vocab_size=len(t5_vocab),
            d_model=32,
            d_kv=8,
            d_ff=37,
            num_layers=1,
            num_heads=4,
            pad_token_id=0,
            eos_token_id=1,
            decoder_start_token_id=0,
        )
    )
    # latent_channels 1, packed 2 x 2: the transformer sees 4 channels.
    transformer = diffusers.FluxTransformer2DModel(
        patch_size=1,
        in_channels=4,
        num_layers=1,
        num_single_layers=1,
        attention_head_dim=16,
        num_attention_heads=2,
        joint_attention_dim=32,
        pooled_projection_dim=32,
        axes_dims_rope=[4, 4, 8],
    )
    vae = diffusers.AutoencoderKL(
        sample_size=32,
        in_channels=3,
        out_channels=3,
        block_out_channels=(4,),
        layers_per_block=1,
        latent_channels=1,
        norm_num_groups=1,
        use_quant_conv=False,
        use_post_quant_conv=False,
        shift_factor=0.0609,
        scaling_factor=1.5035,
    )
    pipe = diffusers.FluxPipeline(
        scheduler=diffusers.FlowMatchEulerDiscreteScheduler(),
        vae=vae,
        text_encoder=clip,
        tokenizer=clip_tokenizer,
        text_encoder_2=t5,
        tokenizer_2=t5_tokenizer,
        transformer=transformer,
    )
    pipe.save_pretrained(folder / "pipeline")
    return folder / "pipeline"


def tiny_sam(folder: Path) -> Path:
    """A SamModel for 64 px inputs (8 px patches, two vision layers) and its processor."""
    torch.manual_seed(0)
    config = transformers.SamConfig(
        vision_config=transformers.SamVisionConfig(
            hidden_size=16,
            output_channels=8,
            num_hidden_layers=2,
            num_attention_heads=2,
            mlp_dim=32,
            image_size=64,
            patch_size=8,
            global_attn_indexes=[1],
            window_size=4,
            num_pos_feats=4,
        ),
        prompt_encoder_config=transformers.SamPromptEncoderConfig(
            hidden_size=8, image_size=64, patch_size=8, mask_input_channels=4
        ),
        mask_decoder_config=transformers.SamMaskDecoderConfig(
            hidden_size=8, num_hidden_layers=2, num_attention_heads=2, mlp_dim=16
        ),
    )
    processor = transformers.SamProcessor(
        image_processor=transformers.SamImageProcessor(
            size={"longest_edge": 64},
            pad_size={"height": 64, "width": 64},
            mask_size={"longest_edge": 16},
            mask_pad_size={"height": 16, "width": 16},
        )
    )
    transformers.SamModel(config).save_pretrained(folder)
    processor.save_pretrained(folder)
    return folder


def tiny_depth_anything(folder: Path) -> Path:
    """A metric DepthAnythingForDepthEstimation on a four-layer DINOv2 of width 16 and its
    DPT processor (56 px inputs)."""
    torch.manual_seed(0)
    backbone = transformers.Dinov2Config(
        hidden_size=16,
        num_hidden_layers=4,
        num_attention_heads=2,
        intermediate_size=32,
        image_size=56,
        patch_size=14,
        out_features=["stage1", "stage2", "stage3", "stage4"],
        reshape_hidden_states=False,
    )
    config = transformers.DepthAnythingConfig(
        backbone_config=backbone,
        reassemble_hidden_size=16,
        patch_size=14,
        neck_hidden_sizes=[8, 8, 16, 16],
        fusion_hidden_size=8,
        head_hidden_size=4,
        depth_estimation_type="metric",
        max_depth=20,
    )
    transformers.DepthAnythingForDepthEstimation(config).save_pretrained(folder)
    processor = transformers.DPTImageProcessor(
        size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14
    )
    processor.save_pretrained(folder)
    return folder


@pytest.fixture(scope="module")
def weights(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("weights")
    return {
        "flux": tiny_flux(root / "flux"),
        "sam": tiny_sam(root / "sam"),
        "depth": tiny_depth_anything(root / "depth"),
    }


def _generate_cfg(size: int = SIZE, **changes) -> GenerateCfg:
    """Small images: the learned models and the render backend run in seconds."""
    sim_view = SimViewCfg(width=size, height=size)
    return dataclasses.replace(GenerateCfg(width=size, height=size, sim_view=sim_view), **changes)


@pytest.fixture(scope="module")
def rendered(tiny_scene, tmp_path_factory) -> Path:
    """tiny's images from the render backend: with ground truth to score against."""
    out = tmp_path_factory.mktemp("generate_render")
    generate_scenario("tiny", tiny_scene, out, _generate_cfg(RENDERED), seed=0)
    return out


def test_flux_generates_the_images_and_says_they_have_no_ground_truth(
    weights, tiny_scene, tmp_path
):
    flux = FluxCfg(weights_dir=str(weights["flux"]), steps=2, max_sequence_length=32)
    metrics = generate_scenario(
        "tiny", tiny_scene, tmp_path, _generate_cfg(backend="flux", flux=flux), 0
    )
    prompts = read_json(tmp_path / PROMPTS_FILE, PROMPTS)
    assert prompts["backend"] == "flux" and prompts["subtasks"]
    for entry in prompts["subtasks"]:
        image = read_png(tmp_path / entry["image"], "generate")
        assert image.shape == (SIZE, SIZE, 3) and image.dtype == np.uint8
        assert image.std() > 0  # an image, if of noise
    assert metrics["ground_truth"] is False and "no ground truth" in metrics["not_scored"]
    assert not any((tmp_path / GROUND_TRUTH_DIR).iterdir())  # empty: DVC's output exists
    # The masks stage cannot prompt a segmenter without the true box: it says so.
    with pytest.raises(ConfigError, match="open-vocabulary detector"):
        masks_scenario("tiny", tmp_path, tmp_path / "masks", MasksCfg(backend="grabcut"), 0)


def test_flux_is_reproducible_for_a_seed(weights):
    from locoman.perception.flux import generate_image, load_flux_pipeline

    flux = FluxCfg(weights_dir=str(weights["flux"]), steps=2, max_sequence_length=32)
    pipe = load_flux_pipeline(flux)
    cfg = _generate_cfg(backend="flux", flux=flux)
    first = generate_image(pipe, "a person lifts a box", cfg, 3)
    assert np.array_equal(first, generate_image(pipe, "a person lifts a box", cfg, 3))
    assert not np.array_equal(first, generate_image(pipe, "a person lifts a box", cfg, 4))


def test_sam_masks_run_through_the_stage_and_are_scored(weights, rendered, tmp_path):
    cfg = MasksCfg(backend="sam", sam_weights_dir=str(weights["sam"]))
    metrics = masks_scenario("tiny", rendered, tmp_path, cfg, 0)
    prompts = read_json(rendered / PROMPTS_FILE, PROMPTS)
    for entry in prompts["subtasks"]:
        masks = read_npz(tmp_path / SUBTASKS_DIR / f"subtask_{entry['index']}.npz", MASKS)
        assert masks["object_mask"].shape == (RENDERED, RENDERED) and masks["object_mask"].any()
        assert masks["object_mask"].dtype == bool
    # Scored against the render backend's truth, beside the other backends.
    assert set(metrics["backends"]) == {"render", "grabcut", "sam"}
    assert 0.0 <= metrics["mask_iou"] <= 1.0
    assert metrics["backends"]["render"]["mask_iou_median"] == 1.0


def test_depth_anything_clouds_run_through_the_stage_and_are_scored(weights, rendered, tmp_path):
    masks_scenario("tiny", rendered, tmp_path / "masks", MasksCfg(), 0)
    cfg = CloudsCfg(depth="depth_anything", depth_weights_dir=str(weights["depth"]))
    metrics = clouds_scenario(
        "tiny", rendered, tmp_path / "masks", tmp_path / "clouds", cfg, DepthErrorCfg(), 0
    )
    for row in metrics["per_subtask"]:
        clouds = read_npz(
            tmp_path / "clouds" / SUBTASKS_DIR / f"subtask_{row['index']}.npz", CLOUDS
        )
        assert clouds["depth_m"].shape == (RENDERED, RENDERED)
        assert clouds["depth_m"].dtype == np.float32
        assert clouds["points_gen_m"].shape[1] == 3 and len(clouds["points_gen_m"]) >= 3
    assert metrics["depth"] == "depth_anything" and metrics["depth_scale"] is None
    assert np.isfinite(metrics["chamfer_m"])  # scored against the true surface


def test_cuda_asked_for_and_absent_is_an_error_not_a_cpu_run():
    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    with pytest.raises(ModelError, match=r"flux\.runtime\.device = 'cuda'.*no CUDA"):
        torch_runtime(TorchCfg(device="cuda"), "perception.generate.flux.runtime")
    device, dtype = torch_runtime(TorchCfg(dtype="bfloat16"), "x")
    assert device.type == "cpu" and dtype == torch.bfloat16


@pytest.mark.parametrize(
    ("device", "dtype", "key"),
    [("gpu", "float32", "device"), ("cpu", "float64", "dtype"), ("cpu", "float16", "dtype")],
)
def test_runtime_config_refuses_what_torch_cannot_run(device, dtype, key):
    assert key in dict(TorchCfg(device=device, dtype=dtype).check())


def test_bfloat16_on_the_cpu_runs_the_depth_model(weights, rendered):
    from locoman.perception.depth import DepthAnythingEstimator

    rgb = read_png(subtask_dir(rendered, 0) / "image.png", "generate")
    depth = DepthAnythingEstimator(str(weights["depth"]), TorchCfg(dtype="bfloat16"))(rgb)
    assert depth.shape == rgb.shape[:2] and depth.dtype == np.float32
